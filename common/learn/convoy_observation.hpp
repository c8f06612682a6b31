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

#include "convoy/follower.hpp"
#include "convoy/obstacle_memory.hpp"
#include "core/state_io.hpp"
#include "learn/env.hpp"
#include "protocol/agent.hpp"
#include "scenario/scenario.hpp"
#include "sensors/geodesy.hpp"

namespace syndds::learn {

/// Which numbers the observation's vector holds (docs/learning.md, "Observation"):
/// - paper: the paper's four, [north_m, east_m, heading_rad, closing_mps] of the leader
///   relative to the follower, straight from the newest readings;
/// - trail: the classical follower's estimator (convoy::ConvoyFollower: filtered own and
///   leader positions, the leader's breadcrumb trail) run on the same readings, and its
///   estimates in the follower's frame: distance and heading to the trail, the trail's
///   curvature ahead, speeds, the gap along the trail, the leader's relative place;
/// - trail_action: trail's numbers and the controller's previous action (steering,
///   throttle/brake, as applied: clamped), so that a policy can know, and be paid for, how
///   much it changes its command;
/// - trail_ff: trail's numbers and the estimator's feed-forward steering (the curvature just
///   ahead turned into a steering input with the understeer the estimator learns from the
///   own steering and compass: how much more this ground needs);
/// - trail_ff_memory: trail_ff's numbers and the policy's memory: a third action, which only
///   comes back in the next observation (clamped to [-1, 1], 0 before the first action), so
///   that a feed-forward policy can carry what it saw (an obstacle that has left the camera's
///   view) from one step to the next. Its teacher value is the map teacher's shift over its
///   largest (KeepOut, 0 without a map).
enum class ConvoyObservationKind { paper, trail, trail_action, trail_ff, trail_ff_memory };
/// Whether a kind runs the trail estimator.
bool observes_trail(ConvoyObservationKind kind);
/// Whether a kind has the memory action (trail_ff_memory).
bool has_memory(ConvoyObservationKind kind);
/// The convoy action of a kind: [steering, throttle_brake] in [-1, 1], and for a kind with a
/// memory the memory in [-1, 1], which a trainer does not explore in (Box::explore).
Box convoy_action_space(ConvoyObservationKind kind);
/// std::invalid_argument naming `name` if it is none of them.
ConvoyObservationKind parse_observation_kind(const std::string& name);
/// Whether a kind's vector has the estimator's feed-forward steering (trail_ff,
/// trail_ff_memory), and where: kFeedforwardIndex.
bool has_feedforward(ConvoyObservationKind kind);
inline constexpr std::size_t kFeedforwardIndex = 12;

struct ConvoyObservationConfig {
  ConvoyObservationKind kind = ConvoyObservationKind::paper;
  std::string follower_id;
  std::string leader_id;
  sensors::Geodetic geodetic_origin;  // of the follower's GPS (its rig)
  sensors::GeodeticModel geodetic_model = sensors::GeodeticModel::wgs84;
  double wheel_radius_m = 0.0;        // the tachometer's spin times this is the own speed
  std::optional<ImageSpec> image;     // the camera's frame size; absent: no image
  std::string camera_id;              // the observed camera (the rig's first): others' images
                                      // (e.g. a chase camera's) are not the policy's
  // The trail kind's estimator: its configuration (leader, filter gains; the control gains
  // are unused) and the vehicles' dimensions.
  convoy::FollowerConfig estimator;
  convoy::FollowerVehicle vehicle;
  /// The teacher's map (training only): obstacles the classical command (classical_action)
  /// keeps clear of. The observation does not see it: its numbers are the same with or
  /// without a map.
  convoy::KeepOut teacher_keep_out;
  /// The teacher's map is not given but perceived: its obstacles are the cells of an
  /// convoy::ObstacleMemory that observe_ranges fills (teacher_keep_out.obstacles unused).
  bool teacher_keep_out_perceived = false;
  /// The observation's cross_track_m is the distance to the trail the teacher tracks: the
  /// estimator's less the teacher's keep-out shift (a policy that tracks the trail then keeps
  /// clear as the teacher does). Off: the observation does not see the map.
  bool observe_keep_out = false;
};

/// The observation's configuration for `follower` of `scenario` following `leader_id`: its
/// GPS's origin and model, its wheel radius, its first camera's frame size (if any), and for
/// the trail kind the estimator's dimensions of both vehicles. Throws std::invalid_argument if
/// the follower has no GPS.
ConvoyObservationConfig convoy_observation_config(
    const scenario::Scenario& scenario, const scenario::VehicleConfig& follower,
    const std::string& leader_id, ConvoyObservationKind kind = ConvoyObservationKind::paper);

class ConvoyObservationBuilder {
 public:
  explicit ConvoyObservationBuilder(ConvoyObservationConfig config);

  /// The vector's names and bounds of a kind (observations are not clipped).
  static Box vector_space(ConvoyObservationKind kind = ConvoyObservationKind::paper);
  ObservationSpace space() const { return {vector_space(config_.kind), config_.image}; }
  ConvoyObservationKind kind() const { return config_.kind; }

  /// Takes the newest reading of each kind among `samples` (other vehicles' samples and other
  /// topics are ignored; a sample older than the one held is ignored), the inputs of frame
  /// `ctx.frame` (stamped k-1); the trail kind's estimator updates for the end of frame k-1.
  void consume(const proto::FrameContext& ctx, const proto::FrameSamples& samples);
  /// Every input has arrived at least once (own fix, heading, speed, the leader's V2V, the
  /// image if there is a camera).
  bool ready() const;
  const ConvoyObservationConfig& config() const { return config_; }
  /// The observation from the newest readings. Throws std::logic_error before ready().
  Observation observation() const;
  /// The trail kinds: the classical follower's command for now (its estimator is the classical
  /// follower, run on the same readings) as a convoy action [steering, throttle_brake] (and,
  /// with a memory, the teacher's keep-out shift over its largest: what to remember); the
  /// teacher a trainer may imitate (ConvoyEnv::expert_action). Empty for the paper kind and
  /// before the estimator's first update; not checkpointed (the next frame recomputes it).
  std::vector<float> classical_action() const { return classical_action_; }
  /// The classical command's steering without the steering lock (ConvoyFollower::
  /// steering_beyond_lock), as classical_action's: 0 before the estimator's first update,
  /// not checkpointed.
  double classical_steering_beyond_lock() const { return classical_beyond_lock_; }
  /// The action the controller applies from now on (clamped to [-1, 1], NaN as 0, as
  /// convoy_driver_inputs applies it); the trail_action kind observes it. Before the first:
  /// steering 0, brake 1 (the brake the controllers hold until they act).
  /// `memory`: the memory action (kinds with one; ignored by the others), clamped likewise.
  void note_action(double steering, double throttle_brake, double memory = 0.0);
  /// With teacher_keep_out_perceived: a camera's range reading, placed by the estimator's
  /// own position and heading into the teacher's obstacle memory, whose cells become the
  /// teacher's map from the next frame on. Ignored otherwise and before the estimator has a
  /// position. The memory is checkpointed.
  void observe_ranges(const convoy::RangeReading& reading);
  /// The teacher's keep-out shift of the estimator's last update (m, > 0 left; 0 without a map).
  double teacher_shift_m() const { return teacher_shift_m_; }
  /// The teacher's perceived obstacle cells (empty without teacher_keep_out_perceived).
  const convoy::ObstacleMemory& teacher_memory() const { return teacher_memory_; }

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
  std::optional<convoy::ConvoyFollower> estimator_;  // the trail kinds'
  std::vector<float> classical_action_;               // the estimator's newest command
  double classical_beyond_lock_ = 0.0;                // its steering without the lock
  double previous_steering_ = 0.0;                    // note_action's
  double previous_throttle_brake_ = -1.0;
  double memory_ = 0.0;                               // note_action's (memory kinds)
  convoy::ObstacleMemory teacher_memory_;             // teacher_keep_out_perceived's
  double teacher_shift_m_ = 0.0;                      // the estimator's last keep-out shift
};

}  // namespace syndds::learn
