#include "sensors/random.hpp"

#include <array>
#include <sstream>

#include "core/hash.hpp"
#include "core/state_io.hpp"

namespace syndds::sensors {

std::uint64_t derive_seed(std::uint64_t scenario_seed, std::string_view stream) {
  const std::uint64_t h = fnv1a64(stream);
  std::seed_seq seq{static_cast<std::uint32_t>(scenario_seed),
                    static_cast<std::uint32_t>(scenario_seed >> 32), static_cast<std::uint32_t>(h),
                    static_cast<std::uint32_t>(h >> 32)};
  std::array<std::uint32_t, 2> out{};
  seq.generate(out.begin(), out.end());
  return (static_cast<std::uint64_t>(out[1]) << 32) | out[0];
}

// The engine's text form is fixed by the standard (its 312 words and position), so it reads
// back into the same sequence on any library. The spare half of a Box-Muller pair is the next
// normal() when has_spare_ is set: losing it would shift every later variate.
void NormalRng::save_state(core::StateWriter& w) const {
  w.begin("normal_rng", 1);
  std::ostringstream engine;
  engine << engine_;
  w.io(engine.str());
  w.io(spare_);
  w.io(has_spare_);
  w.end();
}

void NormalRng::load_state(core::StateReader& r) {
  r.begin("normal_rng", 1);
  std::istringstream engine(r.get<std::string>());
  engine >> engine_;
  if (!engine) r.fail("the random engine's state cannot be read");
  r.io(spare_);
  r.io(has_spare_);
  r.end();
}

double inverse_normal_cdf(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,
                                 -2.759285104469687e+02, 1.383577518672690e+02,
                                 -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02,
                                 -1.556989798598866e+02, 6.680131188771972e+01,
                                 -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01,
                                 -2.400758277161838e+00, -2.549732539343734e+00,
                                 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01,
                                 2.445134137142996e+00, 3.754408661907416e+00};
  constexpr double p_low = 0.02425;
  if (p < p_low) {
    const double q = std::sqrt(-2.0 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  }
  if (p > 1.0 - p_low) {
    const double q = std::sqrt(-2.0 * std::log(1.0 - p));
    return -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  }
  const double q = p - 0.5;
  const double r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
}

NormalTable::NormalTable() {
  for (int i = 0; i < 65536; ++i) {
    values_[i] = static_cast<float>(inverse_normal_cdf((i + 0.5) / 65536.0));
  }
  // Midpoint quantiles lose a little variance in the clipped tails: rescale to unit variance.
  double sum_sq = 0.0;
  for (float v : values_) sum_sq += static_cast<double>(v) * v;
  const double scale = 1.0 / std::sqrt(sum_sq / 65536.0);
  for (float& v : values_) v = static_cast<float>(v * scale);
}

const NormalTable& NormalTable::instance() {
  static const NormalTable table;
  return table;
}

}  // namespace syndds::sensors
