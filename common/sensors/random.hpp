#pragma once
// Explicitly seeded random streams (no global RNG). Every sensor owns its streams, seeded from
// the scenario seed and a stream name ("<vehicle>/<sensor>"), so results do not depend on the
// order sensors are created in, on thread counts, or on other sensors.
//
// Two kinds of generator:
//  - NormalRng: a sequential stream (std::mt19937_64, whose output the C++ standard fixes,
//    plus our own Box-Muller so the normal variates do not depend on the standard library);
//  - counter-based normals (hash_normal): a pure function of (key, counter), used for image
//    noise so every pixel's noise is independent of which thread renders it.
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <string_view>

#include "core/hash.hpp"

namespace syndds::core {
class StateWriter;
class StateReader;
}  // namespace syndds::core

namespace syndds::sensors {

/// Seed of the random stream `stream` in a scenario seeded with `scenario_seed`
/// (std::seed_seq over the scenario seed and a stable hash of the name).
std::uint64_t derive_seed(std::uint64_t scenario_seed, std::string_view stream);

/// SplitMix64 finaliser: a well-mixed 64-bit hash of a 64-bit value.
inline std::uint64_t mix64(std::uint64_t x) { return splitmix64(x); }

/// Sequential generator of uniform and standard normal variates.
class NormalRng {
 public:
  explicit NormalRng(std::uint64_t seed) : engine_(seed) {}
  /// Uniform in (0, 1), 53 random bits.
  double uniform() {
    return (static_cast<double>(engine_() >> 11) + 0.5) * (1.0 / 9007199254740992.0);
  }
  /// Standard normal (Box-Muller, both variates used).
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double r = std::sqrt(-2.0 * std::log(uniform()));
    const double phi = 2.0 * std::numbers::pi * uniform();
    spare_ = r * std::sin(phi);
    has_spare_ = true;
    return r * std::cos(phi);
  }
  double normal(double std_dev) { return std_dev == 0.0 ? 0.0 : std_dev * normal(); }

  /// Checkpoint state: the engine (its standard text form, exact) and the spare variate.
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  std::mt19937_64 engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

/// Table of 2^16 standard-normal quantiles at (i + 0.5) / 2^16: a normal variate from one
/// 16-bit slice of a hash, exact in distribution up to the quantisation (tails to 4.3 sigma).
class NormalTable {
 public:
  static const NormalTable& instance();  // immutable after first use
  float operator()(std::uint32_t index16) const { return values_[index16 & 0xFFFFu]; }

 private:
  NormalTable();
  float values_[65536];
};

/// Inverse of the standard normal CDF (Acklam's rational approximation, |rel err| < 1.2e-9).
double inverse_normal_cdf(double p);

}  // namespace syndds::sensors
