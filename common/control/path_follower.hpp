#pragma once
// Path-following driver in the style of Chrono's demos: a lateral PID on the offset between a
// sentinel point `lookahead_m` ahead of the vehicle and the path point closest to it, and a
// speed PID toward a target speed profile; one signal split into throttle (> 0) or brake (< 0).
// On an open path the target speed tapers to stop at the end.
#include "control/path.hpp"
#include "control/pid.hpp"
#include "core/state_io.hpp"
#include "vehicle/vehicle_model.hpp"

namespace syndds::control {

struct SpeedProfile {
  enum class Kind { constant, ramp };
  Kind kind = Kind::constant;
  double target_mps = 5.0;   // constant value, or the cap of the ramp
  double accel_mps2 = 0.47;  // ramp slope (the paper's convoy leaders)
  double start_mps = 0.0;    // ramp start value
  double at(double time_s) const {
    if (kind == Kind::constant) return target_mps;
    return std::min(target_mps, start_mps + accel_mps2 * time_s);
  }
};

struct PathFollowerConfig {
  double lookahead_m = 5.0;
  PidGains steering{0.4, 0.1, 0.2};
  PidGains speed{0.4, 0.0, 0.0};
  SpeedProfile speed_profile;
  double stop_decel_mps2 = 1.5;  // comfortable deceleration used to stop at an open path's end
};

class PathFollower {
 public:
  PathFollower(Path path, PathFollowerConfig config);

  /// One control update from the vehicle's pose and world velocity at `time_s`.
  vehicle::DriverInputs update(double time_s, const Pose& pose, const Vec3& velocity, double dt);

  const Path& path() const { return path_; }
  double progress_m() const { return progress_s_; }
  double target_speed_mps() const { return target_speed_; }
  double lateral_error_m() const { return lateral_error_; }

  /// Checkpoints: the controllers' memories and the progress along the path.
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  template <typename Archive>
  void state_io(Archive& a);

  Path path_;
  PathFollowerConfig config_;
  Pid steering_pid_;
  Pid speed_pid_;
  double progress_s_ = -1.0;
  double target_speed_ = 0.0;
  double lateral_error_ = 0.0;
};

}  // namespace syndds::control
