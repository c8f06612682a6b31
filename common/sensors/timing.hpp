#pragma once
// When a sensor measures and when its data becomes available, in whole ticks.
//
// A sensor is fed at a fixed tick (the dynamics step for interoceptive sensors, the frame for
// rendered ones). Measurement k is due at tick T_k = ceil(k * P) with P = 1 / (rate * tick):
// an integer P (100 Hz on 2 ms steps: every 5 ticks) is honoured exactly, a fractional one
// (30 Hz on 10 ms frames: ticks 0, 4, 7, 10, 14, ...) averages to the rate without drift.
// The measurement carries time T_k * tick; it becomes available `lag_ticks` later, where
// lag_ticks = lag / tick rounded up (exact when the lag is a whole number of ticks).
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "core/state_io.hpp"

namespace syndds::sensors {

/// Stamps every sample carries.
struct SampleStamp {
  std::uint64_t sequence = 0;  // measurement index k (0, 1, 2, ...)
  double time_s = 0.0;         // measurement time (start of the collection window)
  double available_s = 0.0;    // time_s + lag: when a consumer may see it

  template <typename Archive>
  void state(Archive& a) {
    a.io(sequence);
    a.io(time_s);
    a.io(available_s);
  }
  void state(core::StateWriter& w) const { const_cast<SampleStamp*>(this)->state<core::StateWriter>(w); }
};

class SampleClock {
 public:
  /// Throws std::invalid_argument when rate > 1 / tick, rate <= 0, lag < 0 or tick <= 0.
  SampleClock(double rate_hz, double lag_s, double tick_s, const std::string& sensor_id);

  double tick_s() const { return tick_s_; }
  double rate_hz() const { return rate_hz_; }
  std::int64_t lag_ticks() const { return lag_ticks_; }
  double period_ticks() const { return period_ticks_; }

  /// Nearest tick of a time on the tick grid.
  std::int64_t tick_of(double time_s) const;
  double time_of(std::int64_t tick) const { return static_cast<double>(tick) * tick_s_; }
  /// Tick of measurement k.
  std::int64_t trigger_tick(std::uint64_t k) const;

  /// Call once per tick (ticks increasing). Returns the measurement index due at this tick,
  /// if any. A skipped tick makes the measurement happen at the next tick fed.
  std::optional<std::uint64_t> trigger(std::int64_t tick);
  /// Whether trigger(tick) would return a measurement (true before the first tick is fed),
  /// and which one (when started).
  bool due(std::int64_t tick) const { return !started_ || tick >= next_tick_; }
  std::uint64_t next_index() const { return next_k_; }

  SampleStamp stamp(std::uint64_t k, std::int64_t tick) const {
    return {k, time_of(tick), time_of(tick + lag_ticks_)};
  }

  /// Checkpoint state: where the schedule stands (started, next measurement and its tick),
  /// after the tick, period and lag it was built with; load refuses a clock built otherwise
  /// (`sensor_id` names it in the message).
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r, const std::string& sensor_id);

 private:
  double rate_hz_;
  double tick_s_;
  double period_ticks_;
  std::int64_t lag_ticks_;
  bool started_ = false;
  std::uint64_t next_k_ = 0;
  std::int64_t next_tick_ = 0;
};

/// Samples waiting for their available time (lag is constant, so FIFO order is release order).
template <typename Sample>
class LagQueue {
 public:
  void push(Sample sample, std::int64_t available_tick) {
    items_.push_back({available_tick, std::move(sample)});
  }
  /// Removes and returns every sample available at or before `tick`.
  std::vector<Sample> take_ready(std::int64_t tick) {
    std::vector<Sample> out;
    while (!items_.empty() && items_.front().first <= tick) {
      out.push_back(std::move(items_.front().second));
      items_.pop_front();
    }
    return out;
  }
  std::size_t pending() const { return items_.size(); }

  /// Checkpoint state: every waiting sample with its available tick, in release order;
  /// `write(w, sample)` / `read(r, sample)` encode one sample.
  template <typename Write>
  void save_state(core::StateWriter& w, Write&& write) const {
    w.io(static_cast<std::uint64_t>(items_.size()));
    for (const auto& [tick, sample] : items_) {
      w.io(tick);
      write(w, sample);
    }
  }
  template <typename Read>
  void load_state(core::StateReader& r, Read&& read) {
    items_.clear();
    const auto n = r.get<std::uint64_t>();
    for (std::uint64_t k = 0; k < n; ++k) {
      std::pair<std::int64_t, Sample> item;
      r.io(item.first);
      read(r, item.second);
      if (!items_.empty() && item.first < items_.back().first) {
        r.fail("waiting samples are not in release order: the state is damaged");
      }
      items_.push_back(std::move(item));
    }
  }

 private:
  std::deque<std::pair<std::int64_t, Sample>> items_;
};

}  // namespace syndds::sensors
