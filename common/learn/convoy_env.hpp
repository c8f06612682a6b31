#pragma once
// The convoy-follow environment (docs/learning.md, "Convoy-follow environment"): a follower
// vehicle that has to keep behind a leader driving an S- or C-shaped path among obstacles,
// simulated by the project's own agents (vehicles, the leader's path follower, sensors, V2V)
// stepped frame by frame. The follower's controller is ConvoyDriverAgent, the member
// external/follower: it builds the observation from the samples it subscribes to and writes
// the current action as its DriverCommand every frame, exactly as a policy controller would
// over DDS. One step = one control period of 10 frames (0.1 s).
#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "agents/sensor_agent.hpp"
#include "learn/convoy_episode.hpp"
#include "learn/convoy_observation.hpp"
#include "learn/env.hpp"
#include "protocol/local_runner.hpp"
#include "scenario/scenario.hpp"

namespace syndds::learn {

/// The reward's constants: r = 1 / (1 + |d - optimal_gap_m| / width_m) while the leader is
/// within +-heading_window_rad of the follower's nose, `outside` otherwise; `collision` and
/// `lost` replace it in the step that ends the episode so.
struct ConvoyRewardParams {
  double optimal_gap_m = 15.0;
  double width_m = 5.0;
  double heading_window_rad = 0.7853981633974483;  // pi / 4
  double outside = -0.1;
  double collision = -10.0;
  double lost = -10.0;
  double track_width_m = 0.5;  // the track reward's: 0.5 at this distance from the path
  /// The track reward's smoothness term: minus this times the square of the change of the
  /// (clamped) steering from the previous step (0: none; docs/learning.md measures 0.1).
  double steer_change = 0.0;
};

/// The reward of a step at centre distance `distance_m` with the leader `heading_diff_rad`
/// off the follower's nose (neither a collision nor a lost leader).
double convoy_reward(double distance_m, double heading_diff_rad, const ConvoyRewardParams& p);

/// Which reward the environment gives (docs/learning.md, "Reward"): `paper`, the gap in the
/// leader-in-view window above; `track`, the same gap term times 1 / (1 + e / track_width_m),
/// e the follower's distance from the leader's path (ground truth), less steer_change times the
/// squared change of steering: a follower is paid for driving smoothly where the leader drove,
/// not for keeping the gap on any line.
enum class ConvoyRewardKind { paper, track };

/// The track reward of a step: the gap term (no view window) times the track term.
double convoy_track_reward(double distance_m, double path_error_m, const ConvoyRewardParams& p);

struct ConvoyEnvOptions {
  ConvoyTerrain terrain = ConvoyTerrain::rigid;
  ConvoyDynamics dynamics = ConvoyDynamics::reduced;
  bool camera = false;             // the 80 x 45 front-bumper camera in the observation
  ConvoyObservationKind observation = ConvoyObservationKind::paper;  // the vector's numbers
  ConvoyRewardKind reward_kind = ConvoyRewardKind::paper;
  double target_speed_mps = 5.0;   // the leader's ramp cap
  /// Above target_speed_mps: each episode's cap is drawn uniformly in [target_speed_mps,
  /// target_speed_max_mps] from its seed (else every episode has target_speed_mps).
  double target_speed_max_mps = 0.0;
  int frames_per_step = 10;        // control period in frames of kConvoyEnvHeartbeatS: 0.1 s
  /// The policy's steering reaches the vehicle through a first-order lag of this time
  /// constant, applied once per action (convoy_lagged_steering; the policy controller applies
  /// the same); 0: directly.
  double steer_lag_s = 0.0;
  /// The action's steering is a correction to the estimator's feed-forward steering in the
  /// observation the policy saw: the command is feedforward_steering + action (clamped);
  /// the expert's action is its command minus that feed-forward (convoy_steering_command;
  /// the policy controller applies the same). Needs a kind with the feed-forward (trail_ff,
  /// trail_ff_memory). Off: the action is the command.
  bool steering_residual = false;
  int max_steps = 500;             // truncated after this many steps (50 s)
  /// The camera variant renders only the frames an observation will hold (the newest at each
  /// step's end; 1 of the camera's 3 per step at 30 Hz): observations are the same bit for bit
  /// as with every frame rendered (tested), which stays available for comparison.
  bool render_only_observed = true;
  double lost_distance_m = 40.0;   // terminated when the leader is farther than this
  /// Above 0: the expert (expert_action, the trail kinds' classical command) is given the
  /// episode's obstacles and keeps their edges this far from the trail it tracks
  /// (convoy::KeepOut); the observation and the reward do not change.
  double teacher_keep_clear_m = 0.0;
  /// Above 1: the expert's steering is the classical command without the steering lock
  /// (ConvoyFollower::steering_beyond_lock), within +-teacher_steering_limit, so that a student
  /// imitating it (its action is clamped to [-1, 1] after it) reaches the lock where the
  /// teacher holds it; an expert clamped to the lock is a target a regression undershoots
  /// there. 1: the command as the vehicle receives it.
  double teacher_steering_limit = 1.0;
  /// With teacher_keep_clear_m: the expert keeps clear only of the obstacles the follower's
  /// camera sees at the moment (KeepOut::view_half_angle_rad from the rig's first camera), so
  /// that its shift is a function of what the policy observes now (needs `camera`).
  bool teacher_view_camera = false;
  /// With teacher_keep_clear_m and the camera: the expert keeps clear of the obstacles it has
  /// perceived, not of the map: before each step the camera's ground-truth reading
  /// (perception_target) goes into its convoy::ObstacleMemory (what a perfect perception
  /// network would give it). Excludes teacher_view_camera.
  bool teacher_view_ranges = false;
  /// With teacher_keep_clear_m: the observation's cross-track is measured from the trail the
  /// teacher tracks, shifted clear of the obstacles (ConvoyObservationConfig::
  /// observe_keep_out): a policy that tracks the trail keeps clear with it.
  bool observe_keep_out = false;
  /// teacher_view_ranges' reading from the observation (its image) instead of the ground
  /// truth: a perception network's (set by programs that load one, e.g. syndds_evaluate
  /// --perception; not an option of the registry). Called from the copy's own thread.
  std::function<std::vector<float>(const Observation&)> perceive_ranges;
  /// Rigid terrain only: each episode's ground gets a colour of its own in the camera,
  /// convoy_ground_colour(seed) (domain randomisation: a policy trained on the grey rigid
  /// ground then sees the soils' brown); physics does not change.
  bool random_ground_colour = false;
  /// Rigid terrain only, 0: the ground's friction coefficient is 0.8 in every episode. Above 0:
  /// each episode's is convoy_ground_friction(seed, friction_min), uniform in
  /// [friction_min, 0.8] (domain randomisation of the grip); the rest of the episode's draws
  /// do not change. Measured not to be what soil changes for a student (docs/learning.md).
  double friction_min = 0.0;
  /// Above 0: after the observation is ready, the follower waits, braked, for
  /// convoy_start_hold(seed, start_hold_max_s) (uniform in [0, start_hold_max_s]) while the
  /// leader drives off, so that the episode starts with the leader further ahead on a trail it
  /// has laid (as when soil holds a follower back: gaps of 15-40 m instead of 5-11 m).
  double start_hold_max_s = 0.0;
  ConvoyRewardParams reward;
  ConvoyEpisodeOptions episode;
  std::string config_dir;          // vehicle files and rigs; empty: scenario::default_config_dir()
};

/// The scenario options of the environment's episode `seed` (its run is a little longer than
/// max_steps control periods).
ConvoyScenarioOptions convoy_scenario_options(const ConvoyEnvOptions& options, std::uint64_t seed);

/// The ground colour of episode `seed` with random_ground_colour: a mix of the rigid ground's
/// grey and the soil's brown (sensors::terrain_look "rigid" and "silt"), the share uniform in
/// [0, 1], times a brightness uniform in [0.7, 1.3], from a stream of its own.
std::array<double, 3> convoy_ground_colour(std::uint64_t seed);

/// The rigid ground's friction coefficient of episode `seed` with friction_min above 0:
/// uniform in [friction_min, 0.8], from a stream of its own.
double convoy_ground_friction(std::uint64_t seed, double friction_min);

/// The start hold of episode `seed` with start_hold_max_s above 0: uniform in
/// [0, hold_max_s], from a stream of its own.
double convoy_start_hold(std::uint64_t seed, double hold_max_s);

/// The driver inputs of a convoy action: steering in [-1, 1] (positive left) and one
/// throttle/brake value in [-1, 1] (positive throttle, negative brake), clamped; NaN is 0
/// (straight ahead, coasting).
vehicle::DriverInputs convoy_driver_inputs(double steering, double throttle_brake);

/// The steering a convoy controller applies for a new `action` after `previous` (the one it
/// applied for the last period_s): the clamped action (NaN as 0) without a lag (lag_s <= 0),
/// else previous + (1 - exp(-period_s / lag_s)) (clamped action - previous).
double convoy_lagged_steering(double previous, double action, double lag_s, double period_s);

/// The steering command of a convoy action's steering `action` given the observation vector
/// the policy saw: the action itself, or with options.steering_residual the observation's
/// feed-forward steering plus it (unclamped: convoy_lagged_steering clamps).
double convoy_steering_command(const ConvoyEnvOptions& options, std::span<const float> seen,
                               double action);

/// A hand-written follower on the convoy observation (the baseline a learned policy has to
/// beat): steer toward the leader (2 x its bearing off the nose), pedal by the gap to the
/// optimal 15 m less the closing speed (0.15 (gap - 15) - 0.3 closing). The paper observation
/// only: std::invalid_argument for another.
std::vector<float> convoy_heuristic_action(const Observation& observation);

/// A range finder's reading of the obstacles in a camera's view (the convoy environment's
/// perception target, docs/learning.md "Perception"): `rays` bearings at the centres of equal
/// slices of the horizontal field of view `hfov_rad` about `yaw_rad`, left to right (ray 0 at
/// +hfov/2 - slice/2, angles counter-clockwise); for each, the distance in the ground plane
/// from `camera` to the first obstacle footprint (circle of the obstacle's radius) the ray
/// meets, divided by `range_m` and capped at 1 (1: nothing within range; 0: the camera is
/// inside a footprint). std::invalid_argument for rays < 1, a range or field of view <= 0.
std::vector<float> obstacle_ranges(const Vec2& camera, double yaw_rad, double hfov_rad, int rays,
                                   double range_m, std::span<const ConvoyObstacle> obstacles);
inline constexpr int kPerceptionRays = 16;
inline constexpr double kPerceptionRangeM = 20.0;

/// The subscriptions of a convoy follower's controller: its own GPS, compass, tachometer and
/// camera samples and the V2V messages of the vehicle it follows, and of its trail's source
/// when that is another vehicle (`trail_of`; empty or the leader: none more).
std::vector<proto::Subscription> convoy_driver_subscriptions(const std::string& vehicle_id,
                                                             const std::string& leader_id,
                                                             const std::string& trail_of = "");

/// The external/<follower> member: observation from its inputs, the action as its command.
class ConvoyDriverAgent final : public proto::Agent {
 public:
  /// `teacher_keep_out`: the expert's map (ConvoyObservationConfig::teacher_keep_out, and
  /// ::teacher_keep_out_perceived).
  ConvoyDriverAgent(const scenario::Scenario& scenario, const scenario::VehicleConfig& follower,
                    const std::string& leader_id,
                    ConvoyObservationKind kind = ConvoyObservationKind::paper,
                    const convoy::KeepOut& teacher_keep_out = {},
                    bool teacher_keep_out_perceived = false, bool observe_keep_out = false);

  const std::string& member_id() const override { return member_id_; }
  std::string vehicle_key() const override { return vehicle_id_; }
  proto::MemberKind kind() const override { return proto::MemberKind::external; }
  std::vector<proto::Subscription> subscriptions() const override;
  std::vector<proto::Topic> publications() const override { return {proto::Topic::driver_command}; }
  void step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
            proto::FrameSamples& outputs) override;

  /// steering in [-1, 1] (positive left), throttle_brake in [-1, 1] (positive throttle,
  /// negative brake); clamped. `memory`: the memory action of a kind with one (has_memory).
  void set_action(double steering, double throttle_brake, double memory = 0.0);
  /// The steering of the command (as set, before clamping).
  double steering() const { return steering_; }
  const ConvoyObservationBuilder& observations() const { return builder_; }
  /// ConvoyObservationBuilder::observe_ranges.
  void observe_ranges(const convoy::RangeReading& reading) { builder_.observe_ranges(reading); }

 private:
  std::string vehicle_id_;
  std::string leader_id_;
  std::string member_id_;
  ConvoyObservationBuilder builder_;
  double steering_ = 0.0;
  double throttle_brake_ = -1.0;  // holds the brake until the first action
};

class ConvoyEnv final : public Env {
 public:
  explicit ConvoyEnv(ConvoyEnvOptions options = {});
  ~ConvoyEnv() override;

  ObservationSpace observation_space() const override;
  Box action_space() const override;
  Observation reset(std::uint64_t seed) override;
  StepResult step(std::span<const float> action) override;
  /// The trail kinds: the classical follower's action for the current state, from the
  /// estimator the observation runs (convoy::ConvoyFollower with its default gains, on the
  /// same readings: no ground truth); empty for the paper observation.
  std::vector<float> expert_action() const override;
  /// With the camera: obstacle_ranges(kPerceptionRays, kPerceptionRangeM) from the follower's
  /// camera (its mount's place and field of view) at the ground-truth pose of the last frame,
  /// the pose the image was rendered at less the camera's lag (0.05-0.08 s of driving). Empty
  /// without the camera.
  std::vector<float> perception_target() const override;

  const ConvoyEnvOptions& options() const { return options_; }
  /// The current episode (valid after reset).
  const ConvoyEpisode& episode() const { return episode_; }
  /// Ground truth of the last frame (valid after reset).
  const proto::VehicleStateMsg& follower_state() const { return follower_state_; }
  const proto::VehicleStateMsg& leader_state() const { return leader_state_; }
  /// The expert's keep-out shift of the last frame (m, > 0 left; 0 without a map).
  double teacher_shift_m() const { return driver_ ? driver_->observations().teacher_shift_m() : 0.0; }
  /// The steering the last step applied (after the residual, the clamp and the lag).
  double applied_steering() const { return last_steering_; }
  /// Camera frames the follower's rig has made this episode (0 without a camera).
  std::uint64_t camera_frames() const { return sensor_ ? sensor_->frames_rendered() : 0; }

 private:
  void run_frame();

  ConvoyEnvOptions options_;
  ConvoyEpisode episode_;
  std::optional<scenario::Scenario> scenario_;
  std::unique_ptr<proto::FrameStepper> stepper_;
  ConvoyDriverAgent* driver_ = nullptr;  // owned by stepper_
  agents::SensorAgent* sensor_ = nullptr; // the follower's (camera variant), owned by stepper_
  proto::VehicleStateMsg follower_state_;
  proto::VehicleStateMsg leader_state_;
  proto::VehicleStateMsg head_state_;  // chained episodes: the leader's leader
  double last_steering_ = 0.0;  // the previous step's (clamped) steering
  std::vector<float> seen_;     // the vector of the observation returned last
  bool collided_ = false;
  bool leader_contact_ = false;  // the collision was with the leader
  int steps_ = 0;
  bool running_ = false;
};

/// A convoy environment (for registries of environments by name).
std::unique_ptr<Env> make_convoy_env(const ConvoyEnvOptions& options);

}  // namespace syndds::learn
