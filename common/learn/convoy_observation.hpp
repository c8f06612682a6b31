#pragma once
// The convoy follower's observation, built from the samples a controller member receives (the
// follower's own gps_fix, magnetometer, wheel_speeds and image samples and the V2V messages
// of the vehicle it follows): the same class serves the learning environment (ConvoyEnv, whose
// driver agent is fed by a FrameStepper) and a policy controller fed over DDS, so both see the
// same numbers from the same samples. Definitions: docs/learning.md.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/state_io.hpp"
#include "learn/env.hpp"
#include "protocol/agent.hpp"
#include "scenario/scenario.hpp"
#include "sensors/geodesy.hpp"

namespace syndds::learn {

struct ConvoyObservationConfig {
  std::string follower_id;
  std::string leader_id;
  sensors::Geodetic geodetic_origin;  // of the follower's GPS (its rig)
  sensors::GeodeticModel geodetic_model = sensors::GeodeticModel::wgs84;
  double wheel_radius_m = 0.0;        // the tachometer's spin times this is the own speed
  std::optional<ImageSpec> image;     // the camera's frame size; absent: no image
};

/// The observation's configuration for `follower` of a scenario following `leader_id`: its
/// GPS's origin and model, its wheel radius, its first camera's frame size (if any). Throws
/// std::invalid_argument if the follower has no GPS.
ConvoyObservationConfig convoy_observation_config(const scenario::VehicleConfig& follower,
                                                  const std::string& leader_id);

class ConvoyObservationBuilder {
 public:
  explicit ConvoyObservationBuilder(ConvoyObservationConfig config);

  /// [north_m, east_m, heading_rad, closing_mps], with bounds (observations are not clipped).
  static Box vector_space();
  ObservationSpace space() const { return {vector_space(), config_.image}; }

  /// Takes the newest reading of each kind among `samples` (other vehicles' samples and other
  /// topics are ignored; a sample older than the one held is ignored).
  void consume(const proto::FrameSamples& samples);
  /// Every input has arrived at least once (own fix, heading, speed, the leader's V2V, the
  /// image if there is a camera).
  bool ready() const;
  /// The observation from the newest readings. Throws std::logic_error before ready().
  Observation observation() const;

  /// Checkpoints (docs/checkpoints.md): the newest reading of each kind held, every field.
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  template <typename Archive>
  void state_io(Archive& a);

  ConvoyObservationConfig config_;
  sensors::GeodeticConverter converter_;
  std::optional<proto::GpsFixMsg> fix_;
  std::optional<proto::MagnetometerMsg> compass_;
  std::optional<proto::WheelSpeedsMsg> wheels_;
  std::optional<proto::V2VMessageMsg> v2v_;
  std::optional<proto::ImageMsg> image_;
};

}  // namespace syndds::learn
