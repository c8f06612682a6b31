#pragma once
// Vehicle-to-vehicle broadcasts. A vehicle tells the others where it is from its own sensors:
// the newest GPS fix, compass heading and tachometer speed it holds (noise and lag included),
// never its true state. Each vehicle has its own rate, latency and drop probability
// (`v2v: {rate_hz, latency_s, drop_probability}` in the scenario); drops come from a stream
// seeded by the scenario seed and the vehicle id, so a run is reproducible.
//
// Timing: messages are built at multiples of 1 / rate_hz, evaluated at frame ends (a message
// due inside a frame is built at its end, from the readings available then). A message built at
// t is published in the first frame that ends at or after t + latency_s; the DDS hop adds one
// frame on top (the receiver sees it in the next frame), like every other sample.
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "convoy/v2v_config.hpp"
#include "protocol/messages.hpp"
#include "sensors/random.hpp"
#include "sensors/rig.hpp"

namespace syndds::convoy {

class V2VBroadcaster {
 public:
  /// `wheel_radius_m` turns the tachometer's wheel spin into speed.
  V2VBroadcaster(V2VConfig config, std::string vehicle_id, std::string source,
                 double wheel_radius_m, std::uint64_t scenario_seed);

  /// Feeds the sensor samples that became available (the vehicle's own interoceptive batch).
  void observe(const sensors::InteroceptiveBatch& batch);
  /// Messages to publish in `frame`, which ends at `time_s`.
  std::vector<proto::V2VMessageMsg> step(std::int64_t frame, double time_s);

  const V2VConfig& config() const { return config_; }
  std::uint64_t built() const { return sequence_; }
  std::uint64_t dropped() const { return dropped_; }
  /// Messages built and waiting for their latency.
  std::size_t pending() const { return pending_.size(); }

  /// Checkpoint state (between frames): drop stream, newest readings, counters, messages
  /// waiting for their latency.
  void save_state(core::StateWriter& w) const;
  /// Restores into a broadcaster built for the same vehicle and configuration; throws
  /// core::StateError otherwise.
  void load_state(core::StateReader& r);

 private:
  V2VConfig config_;
  std::string vehicle_id_;
  std::string source_;
  double wheel_radius_m_;
  sensors::NormalRng rng_;
  std::optional<sensors::GpsSample> gps_;
  std::optional<sensors::MagnetometerSample> compass_;
  std::optional<sensors::TachometerSample> tachometer_;
  std::uint64_t sequence_ = 0;  // messages built (the next one's number)
  std::uint64_t dropped_ = 0;
  std::deque<std::pair<double, proto::V2VMessageMsg>> pending_;  // release time, message
};

/// Mean wheel spin of a tachometer sample times the wheel radius: the speed a tachometer tells.
double tachometer_speed(const std::vector<double>& wheel_spin_rad_s, double wheel_radius_m);

}  // namespace syndds::convoy
