#pragma once
// The classical convoy follower: the baseline a learned policy has to beat. It knows only what
// its own sensors (GPS, compass, wheel tachometer) and the V2V messages of the vehicle it
// follows tell it, never a true state. docs/convoy.md explains each step and its reasons.
//
// - Own state: heading from the compass, speed from the tachometer (never falling faster than a
//   vehicle can brake: a locked wheel reads 0 while the vehicle still slides), position
//   dead-reckoned from both at every update and pulled towards each GPS fix (the fix projected
//   to now along the heading to undo its lag) by a complementary gain.
// - Leader: the same filter on its V2V messages (position projected from the message's
//   measurement time with its reported speed and heading); between messages, and when some are
//   dropped or late, dead reckoning carries it on. Its acceleration is the difference of the
//   speeds of consecutive messages over the time between them.
// - Breadcrumb trail: at each V2V message, the leader's filtered position and its compass yaw.
//   Steering tracks the trail, not the leader: the trail's curvature (from the crumbs' yaws)
//   as a feed-forward road-wheel angle (kinematic, plus an understeer term), and feedback on
//   the heading error (the leader's yaw where it drove there) and the cross-track error
//   (Stanley: atan(k e / (v + v0))). No look-ahead point, so no corner is cut.
// - Spacing, bumper to bumper along the trail: desired gap = standstill + time gap * own speed
//   + the difference of the braking distances (own v^2 / 2 b_own less the leader's v_L^2 / 2 d_L
//   at its measured deceleration d_L, when positive); target speed = the leader's speed
//   predicted `anticipation_s` ahead from its acceleration + gap_gain * (gap - desired),
//   clamped to [0, max_speed_mps] (no limit in bends: the leader's speed sets it); a speed PID
//   to one throttle / brake signal.
// - Radar (optional, `radar.sensor`): the nearest detection of the follower's own forward
//   radar that lies in its lane (abs(y) <= lane_half_width_m in the radar frame), within
//   gate_m of the V2V gap, measured at most max_age_s ago, replaces the V2V gap (carried to now
//   by its range rate) and gives the leader's speed as own speed + range rate. Otherwise (no
//   such detection: the leader in a bend, out of the field of view, occluded) the V2V gap.
// - Leader lost: no V2V message measured within `leader_lost_after_s` -> brake to a stop and
//   report `leader_lost` once; a fresh message reports `leader_found` and following resumes.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "control/pid.hpp"
#include "core/math.hpp"
#include "core/state_io.hpp"
#include "protocol/messages.hpp"
#include "sensors/geodesy.hpp"
#include "vehicle/vehicle_model.hpp"

namespace syndds::convoy {

struct FollowerConfig {
  std::string leader;                 // vehicle id of the vehicle followed
  /// Vehicle id whose V2V positions lay the trail the follower steers along; empty (or the
  /// leader): the leader's own. The convoy's head: every follower steers along the same trail
  /// and keeps its spacing to the vehicle ahead, so that an offset from the trail is not
  /// handed down the convoy (behind the leader's trail each follower tracks the one ahead,
  /// offset included, and the offsets add up in bends).
  std::string trail_of;
  // Spacing.
  double time_gap_s = 1.0;
  double standstill_bumper_m = 5.0;   // bumper-to-bumper gap when stopped
  double own_decel_mps2 = 4.0;        // braking the follower counts on for itself
  double anticipation_s = 0.5;        // the leader's speed is predicted this far ahead
  double max_speed_mps = 15.0;
  double gap_gain_per_s = 0.4;
  control::PidGains speed_pid{0.4, 0.05, 0.0};
  // Trail tracking.
  double heading_gain = 1.0;              // road-wheel rad per rad of heading error
  double cross_track_gain_per_s = 1.0;    // Stanley gain k of atan(k e / (v + v0))
  double understeer_rad_per_mps2 = 0.0;   // starting value of the understeer learned (rad of
                                          // road-wheel angle per m/s2 of lateral accel)
  // Estimation.
  double fix_gain = 0.15;             // share of a GPS fix's innovation taken per fix
  double leader_fix_gain = 0.15;      // the same for the leader's V2V positions
  double leader_lost_after_s = 2.0;
  double crumb_spacing_m = 0.3;       // smallest distance between crumbs
  // Radar gap (empty sensor: V2V only).
  std::string radar_sensor;           // id of a radar in the follower's own rig
  double radar_lane_half_width_m = 1.5;
  double radar_gate_m = 3.0;
  double radar_max_age_s = 0.25;
};

/// What the follower needs to know about the vehicle it drives and the one it follows.
struct FollowerVehicle {
  double wheelbase_m = 3.378;
  double half_track_m = 0.9095;
  double max_steer_rad = 0.53;        // road-wheel angle at steering 1
  bool inner_wheel_input = true;      // steering sets the inner wheel (full model), else the
                                      // bicycle's angle (reduced model)
  double wheel_radius_m = 0.467;
  double front_m = 2.35;              // GPS antenna (reference point) to the front bumper
  double leader_rear_m = 2.35;        // the leader's GPS antenna to its rear bumper
  double leader_wheelbase_m = 3.378;
  double trail_wheelbase_m = 3.378;     // the trail's source (FollowerConfig::trail_of)
  double radar_ahead_of_front_m = 0.0;  // the radar's mount ahead of the front bumper
};

/// One sensor reading the follower uses (from GpsFixMsg, MagnetometerMsg, WheelSpeedsMsg).
struct OwnReadings {
  std::vector<proto::GpsFixMsg> gps;
  std::vector<proto::MagnetometerMsg> compass;
  std::vector<proto::WheelSpeedsMsg> wheel_speeds;
};

/// What the follower knows after an update(), as numbers for a learned controller (the trail
/// observation of learn::ConvoyObservationBuilder): its estimates, never a true state.
struct TrailFeatures {
  /// Where along the trail, from the follower's projection on it, the curvatures are read.
  static constexpr std::array<double, 3> kCurvatureAheadM = {0.0, 5.0, 10.0};
  bool valid = false;               // own and leader estimates and a trail exist
  double cross_track_m = 0.0;       // > 0: the follower is left of the trail
  double heading_error_rad = 0.0;   // the trail's yaw at the projection less the own yaw
  std::array<double, 3> curvature_per_m{};  // the trail's (> 0: turning left), 2 m windows
  double own_speed_mps = 0.0;
  double leader_speed_mps = 0.0;
  double leader_accel_mps2 = 0.0;
  double gap_m = 0.0;               // bumper to bumper along the trail
  double leader_forward_m = 0.0;    // the leader's estimate in the follower's frame
  double leader_left_m = 0.0;
  bool leader_lost = false;
  /// The steering command's feed-forward part: the road-wheel angle for the trail's curvature
  /// just ahead, kinematic plus the learned understeer term (the follower's own estimate of
  /// how much more this ground needs), as a steering input in [-1, 1].
  double feedforward_steering = 0.0;
};

/// Obstacles the follower keeps clear of when it is given their map: the learned follower's
/// teacher in training (learn::ConvoyEnv, option `teacher_keep_clear`), never the classical
/// follower member of a scenario. Where the trail passes an obstacle's edge closer than
/// clearance_m, the follower tracks the trail shifted away from that obstacle by the
/// difference (at most max_shift_m), from lead_in_m before the obstacle (reached over
/// ramp_m) to 2 m past it. Obstacles on the two sides push against each other: the shift is
/// the largest push to the left less the largest push to the right. The steering command's
/// cross-track feedback acts on the shifted trail; nothing else changes: the trail, its
/// features, the spacing and every estimate (the understeer learned from the commanded angle
/// included) are those without the map, so a learning environment's observation does not
/// depend on its teacher's map.
struct KeepOut {
  struct Circle {
    Vec2 centre = Vec2::Zero();
    double radius_m = 0.0;
  };
  std::vector<Circle> obstacles;   // empty: no shift
  double clearance_m = 2.5;        // obstacle edge to the trail, wanted at least
  double max_shift_m = 1.5;
  double lead_in_m = 8.0;          // arc length before the obstacle's extent
  double ramp_m = 4.0;
  /// What the follower sees of the map. view_half_angle_rad <= 0: every obstacle, wherever it
  /// is. Above 0: only the obstacles a camera view_ahead_m ahead of the follower's reference
  /// point, looking along its heading, sees now (any part of the circle within
  /// +-view_half_angle_rad of the heading, in front of the camera), both from the follower's
  /// own estimate of its position and heading: a teacher whose shift a student can read
  /// from that camera's current image.
  double view_half_angle_rad = 0.0;
  double view_ahead_m = 0.0;
  /// Whether `ob` is within that view from a follower at `position` heading `yaw` (always
  /// true when view_half_angle_rad <= 0).
  bool in_view(const Circle& ob, const Vec2& position, double yaw) const;
};

struct FollowerEvent {
  std::string kind;    // leader_lost | leader_found
  std::string detail;
};

class ConvoyFollower {
 public:
  ConvoyFollower(FollowerConfig config, FollowerVehicle vehicle,
                 sensors::GeodeticConverter converter);

  /// One control update at `time_s` (the time the newest inputs refer to), `dt` after the
  /// previous one. Returns the command; events that happened are appended to `events`.
  vehicle::DriverInputs update(double time_s, double dt, const OwnReadings& own,
                               const std::vector<proto::V2VMessageMsg>& leader,
                               std::vector<FollowerEvent>& events);

  /// Radar scans of the follower's own vehicle (any sensor: those of `radar_sensor` are used),
  /// before update(). Keeps the newest in-lane detection.
  void observe_radar(const std::vector<proto::RadarScanMsg>& scans);
  /// Whether the last update() took its gap from the radar.
  bool radar_in_use() const { return radar_used_; }

  /// Gives the follower a map of obstacles to keep clear of (KeepOut); none by default.
  void set_keep_out(KeepOut keep_out) { keep_out_ = std::move(keep_out); }
  /// The sideways shift of the trail the last update() tracked (> 0: left; 0 without a map).
  double keep_out_shift_m() const { return keep_shift_; }
  /// The last update()'s steering as it would be without the steering lock: the command's
  /// steering where that is inside [-1, 1], beyond it where the command is held at the lock;
  /// 0 when the update held the brake without steering. For a teacher whose student's action
  /// is clamped after it (learn::ConvoyEnv, option teacher_steering_limit).
  double steering_beyond_lock() const { return steering_beyond_lock_; }
  bool leader_lost() const { return lost_; }
  bool ready() const {
    return own_.has_value() && lead_.estimate.has_value() && trail_source().estimate.has_value();
  }
  Vec2 position_estimate() const { return own_ ? own_->position : Vec2::Zero(); }
  double yaw_estimate() const { return own_ ? own_->yaw : 0.0; }
  Vec2 leader_estimate() const { return lead_.estimate ? lead_.estimate->position : Vec2::Zero(); }
  /// Bumper-to-bumper gap along the trail, as the follower estimates it.
  double gap_m() const { return gap_m_; }
  double desired_gap_m() const { return desired_gap_m_; }
  double target_speed_mps() const { return target_speed_; }
  double leader_accel_mps2() const { return lead_.accel; }
  double cross_track_m() const { return cross_track_m_; }
  double understeer_rad_per_mps2() const { return understeer_; }
  const std::vector<Vec2>& trail() const { return trail_; }
  /// The follower's estimates as of the last update (valid == false before it has any).
  TrailFeatures trail_features() const;

  /// Checkpoints: estimates, the trail of crumbs, the speed controller, the leader watch.
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  template <typename Archive>
  void state_io(Archive& a);

  struct Estimate {
    Vec2 position = Vec2::Zero();
    double yaw = 0.0;     // counter-clockwise from east
    double speed = 0.0;
  };
  /// A vehicle known from its V2V messages: the leader, and the trail's source when that is
  /// another vehicle.
  struct Tracked {
    std::optional<Estimate> estimate;
    double seen_s = -1.0;          // measurement time of the newest message
    std::uint64_t sequence = 0;    // the newest message's
    bool has_sequence = false;
    double speed_time_s = -1.0;    // when the previous message's speed arrived (< 0: none)
    double accel = 0.0;            // m/s2, from consecutive V2V speeds
    double speed = 0.0;            // the previous message's speed and yaw
    double heading_yaw = 0.0;
    double yaw_rate = 0.0;         // rad/s, from consecutive V2V headings
    std::uint64_t fixes = 0;       // V2V positions fused after the first
  };
  template <typename Archive>
  static void tracked_io(Archive& a, Tracked& t);
  void update_own(double time_s, double dt, const OwnReadings& own);
  /// Dead-reckons `t` (vehicle `id`, wheelbase `wheelbase_m`) by dt and fuses its new
  /// messages among `msgs`. Returns true when one was fused (a crumb may be laid).
  bool track(Tracked& t, const std::string& id, double wheelbase_m, double time_s, double dt,
             const std::vector<proto::V2VMessageMsg>& msgs) const;
  /// Whether the trail comes from another vehicle than the leader.
  bool trail_apart() const { return !config_.trail_of.empty() && config_.trail_of != config_.leader; }
  const Tracked& trail_source() const { return trail_apart() ? head_ : lead_; }
  void extend_trail();
  struct Projection {
    std::size_t index = 0;       // trail segment
    double s = 0.0;              // arc length
    double cross_track_m = 0.0;  // > 0: left of the trail
  };
  /// The projection of `p` on the trail, searched forward from segment `from`.
  Projection projection(const Vec2& p, std::size_t from) const;
  Projection projection(const Vec2& p) const { return projection(p, trail_index_); }
  /// The leader's position on the trail (arc length), searched forward from `leader_index_`.
  Projection leader_on_trail() const;
  /// Distance along the trail from the follower's position `s_here` on it to the leader's
  /// reference point (centre to centre).
  double centres_to_leader(double s_here) const;
  /// Arc position of the follower's projection on the trail (monotone); keeps it.
  double project_on_trail(const Vec2& p);
  Vec2 trail_point(double s) const;
  double trail_yaw(double s) const;
  /// Mean curvature of the trail over [s - w, s + w] (within the trail).
  double trail_curvature(double s, double w) const;
  double trail_length() const { return trail_s_.empty() ? 0.0 : trail_s_.back(); }
  /// Steering input in [-1, 1] for a bicycle road-wheel angle (Ackermann inner wheel).
  /// `limit`: the largest input returned (1: the lock; above it, the input the angle would
  /// need with a larger lock).
  double steering_input(double bicycle_angle, double limit = 1.0) const;
  /// Updates the understeer estimate from the own yaw rate and steering.
  void learn_understeer(double dt, double v);
  /// The largest bicycle road-wheel angle the steering reaches.
  double max_bicycle_angle() const;
  /// Road-wheel angle that drives the reference point (mid-wheelbase) on curvature `k`.
  double kinematic_angle(double k) const;

  FollowerConfig config_;
  FollowerVehicle vehicle_;
  sensors::GeodeticConverter converter_;
  control::Pid speed_pid_;
  std::optional<Estimate> own_;
  Tracked lead_;                      // the vehicle followed
  Tracked head_;                      // the trail's source when it is another (trail_apart)
  double speed_reading_ = 0.0;
  std::optional<double> yaw_reading_;
  std::uint64_t own_fixes_ = 0;       // GPS fixes fused after the first
  double compass_time_s_ = -1.0;      // time of the newest compass reading
  double own_yaw_rate_ = 0.0;         // rad/s, from the compass
  double steer_smoothed_ = 0.0;       // commanded road-wheel angle, smoothed like the yaw rate
  double understeer_num_ = 0.0;       // least-squares sums of the understeer estimate
  double understeer_den_ = 0.0;
  double understeer_ = 0.0;           // rad per m/s2 of lateral acceleration
  bool lost_ = false;
  std::vector<Vec2> trail_;
  std::vector<double> trail_yaw_;     // the leader's yaw at each crumb
  std::vector<double> trail_s_;       // arc length at each crumb
  std::size_t trail_index_ = 0;       // segment the follower was last projected on
  std::size_t leader_index_ = 0;      // the leader's, when the trail is another's
  double gap_m_ = 0.0;
  double desired_gap_m_ = 0.0;
  double target_speed_ = 0.0;
  double cross_track_m_ = 0.0;
  KeepOut keep_out_;
  double keep_shift_ = 0.0;           // the last update's keep_out_shift (derived, not state)
  double steering_beyond_lock_ = 0.0; // the last update's, derived, not state
  /// The shift of the trail at arc position `s_here` that keeps the map's obstacles clear.
  double keep_out_shift(double s_here) const;
  // Newest in-lane radar detection: measurement time (< 0: none), bumper gap, range rate.
  double radar_time_s_ = -1.0;
  double radar_gap_m_ = 0.0;
  double radar_range_rate_ = 0.0;
  bool radar_used_ = false;
};

/// Compass heading (clockwise from north) to yaw (counter-clockwise from east), and back.
double yaw_from_heading(double heading_rad);

}  // namespace syndds::convoy
