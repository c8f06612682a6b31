#pragma once
// The classical convoy follower: the baseline a learned policy has to beat. It knows only what
// its own sensors (GPS, compass, wheel tachometer) and the V2V messages of the vehicle it
// follows tell it, never a true state.
//
// - Own state: heading from the compass, speed from the tachometer, position dead-reckoned
//   from both at every update and pulled towards each GPS fix (the fix projected to now along
//   the heading to undo its lag) by a complementary gain.
// - Leader: the same filter on its V2V messages (position projected from the message's
//   measurement time with its reported speed and heading); between messages, and when some are
//   dropped or late, dead reckoning carries it on.
// - Breadcrumb trail: the leader's filtered positions every `crumb_spacing_m`. Steering is pure
//   pursuit on the trail (a look-ahead point on the trail, not the leader's current position,
//   so corners are driven where the leader drove them, not cut).
// - Spacing: gap = distance along the trail to the leader; target speed = leader speed +
//   gap_gain * (gap - (standstill_m + time_gap_s * own speed)), then a speed PID to one
//   throttle / brake signal.
// - Leader lost: no V2V message measured within `leader_lost_after_s` -> brake to a stop and
//   report `leader_lost` once; a fresh message reports `leader_found` and following resumes.
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
  double time_gap_s = 1.0;
  double standstill_m = 10.0;         // centre-to-centre distance when stopped
  double lookahead_min_m = 6.0;
  double lookahead_time_s = 0.6;      // look-ahead = max(min, time * speed)
  double max_speed_mps = 15.0;
  double gap_gain_per_s = 0.4;
  control::PidGains speed_pid{0.4, 0.05, 0.0};
  double fix_gain = 0.15;             // share of a GPS fix's innovation taken per fix
  double leader_fix_gain = 0.15;      // the same for the leader's V2V positions
  double leader_lost_after_s = 2.0;
  double crumb_spacing_m = 0.5;
};

/// What the follower needs to know about the vehicle it drives.
struct FollowerVehicle {
  double wheelbase_m = 3.378;
  double max_steer_rad = 0.53;
  double wheel_radius_m = 0.467;
};

/// One sensor reading the follower uses (from GpsFixMsg, MagnetometerMsg, WheelSpeedsMsg).
struct OwnReadings {
  std::vector<proto::GpsFixMsg> gps;
  std::vector<proto::MagnetometerMsg> compass;
  std::vector<proto::WheelSpeedsMsg> wheel_speeds;
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

  bool leader_lost() const { return lost_; }
  bool ready() const { return own_.has_value() && leader_.has_value(); }
  Vec2 position_estimate() const { return own_ ? own_->position : Vec2::Zero(); }
  Vec2 leader_estimate() const { return leader_ ? leader_->position : Vec2::Zero(); }
  double gap_m() const { return gap_m_; }
  double target_speed_mps() const { return target_speed_; }
  const std::vector<Vec2>& trail() const { return trail_; }

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
  void update_own(double time_s, double dt, const OwnReadings& own);
  void update_leader(double time_s, double dt, const std::vector<proto::V2VMessageMsg>& msgs);
  void extend_trail();
  /// Arc position of the follower on the trail (monotone), and the point `ahead` metres on.
  double project_on_trail(const Vec2& p);
  Vec2 trail_point(double s) const;
  double trail_length() const { return trail_s_.empty() ? 0.0 : trail_s_.back(); }

  FollowerConfig config_;
  FollowerVehicle vehicle_;
  sensors::GeodeticConverter converter_;
  control::Pid speed_pid_;
  std::optional<Estimate> own_;
  std::optional<Estimate> leader_;
  double speed_reading_ = 0.0;
  std::optional<double> yaw_reading_;
  double leader_seen_s_ = -1.0;       // measurement time of the newest leader message
  std::uint64_t leader_sequence_ = 0;
  bool has_leader_sequence_ = false;
  bool lost_ = false;
  std::vector<Vec2> trail_;
  std::vector<double> trail_s_;       // arc length at each crumb
  std::size_t trail_index_ = 0;       // segment the follower was last projected on
  double gap_m_ = 0.0;
  double target_speed_ = 0.0;
};

/// Compass heading (clockwise from north) to yaw (counter-clockwise from east), and back.
double yaw_from_heading(double heading_rad);

}  // namespace syndds::convoy
