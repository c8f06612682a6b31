#include "sensors/timing.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace syndds::sensors {
namespace {
// Ratios that are whole numbers up to floating-point noise count as whole.
constexpr double kTickEps = 1e-7;
}  // namespace

SampleClock::SampleClock(double rate_hz, double lag_s, double tick_s, const std::string& sensor_id)
    : rate_hz_(rate_hz), tick_s_(tick_s) {
  if (!(tick_s > 0.0)) throw std::invalid_argument(sensor_id + ": tick must be positive");
  if (!(rate_hz > 0.0)) throw std::invalid_argument(sensor_id + ": rate_hz must be positive");
  if (!(lag_s >= 0.0)) throw std::invalid_argument(sensor_id + ": lag_s must be >= 0");
  period_ticks_ = 1.0 / (rate_hz * tick_s);
  if (period_ticks_ < 1.0 - kTickEps) {
    std::ostringstream msg;
    msg << sensor_id << ": rate " << rate_hz << " Hz exceeds the update rate " << 1.0 / tick_s
        << " Hz it is fed at";
    throw std::invalid_argument(msg.str());
  }
  lag_ticks_ = static_cast<std::int64_t>(std::ceil(lag_s / tick_s - kTickEps));
}

std::int64_t SampleClock::tick_of(double time_s) const {
  return static_cast<std::int64_t>(std::llround(time_s / tick_s_));
}

std::int64_t SampleClock::trigger_tick(std::uint64_t k) const {
  return static_cast<std::int64_t>(std::ceil(static_cast<double>(k) * period_ticks_ - kTickEps));
}

std::optional<std::uint64_t> SampleClock::trigger(std::int64_t tick) {
  if (!started_) {
    // First tick fed (0 normally; later for a late joiner): start at the first due measurement.
    started_ = true;
    next_k_ = 0;
    if (tick > 0) {
      next_k_ = static_cast<std::uint64_t>(std::floor(static_cast<double>(tick) / period_ticks_));
      while (trigger_tick(next_k_) < tick) ++next_k_;
    }
    next_tick_ = trigger_tick(next_k_);
  }
  if (tick < next_tick_) return std::nullopt;
  const std::uint64_t k = next_k_;
  do {
    ++next_k_;
    next_tick_ = trigger_tick(next_k_);
  } while (next_tick_ <= tick);
  return k;
}

}  // namespace syndds::sensors
