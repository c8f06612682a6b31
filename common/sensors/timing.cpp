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

// Rate, lag and tick come from the configuration; they are written so a state of a sensor
// configured otherwise is refused by name instead of resuming on another schedule.
void SampleClock::save_state(core::StateWriter& w) const {
  w.begin("sample_clock", 1);
  w.io(tick_s_);
  w.io(period_ticks_);
  w.io(lag_ticks_);
  w.io(started_);
  w.io(next_k_);
  w.io(next_tick_);
  w.end();
}

void SampleClock::load_state(core::StateReader& r, const std::string& sensor_id) {
  r.begin("sample_clock", 1);
  const auto tick = r.get<double>();
  const auto period = r.get<double>();
  const auto lag = r.get<std::int64_t>();
  if (tick != tick_s_ || period != period_ticks_ || lag != lag_ticks_) {
    std::ostringstream msg;
    msg << "sensor '" << sensor_id << "' ran on another schedule: tick " << tick << " s, "
        << period << " ticks per measurement, lag " << lag << " ticks in the state; " << tick_s_
        << " s, " << period_ticks_ << ", " << lag_ticks_ << " here";
    r.fail(msg.str());
  }
  r.io(started_);
  r.io(next_k_);
  r.io(next_tick_);
  r.end();
}

}  // namespace syndds::sensors
