#include "control/path_follower.hpp"

#include <algorithm>
#include <cmath>

namespace syndds::control {

PathFollower::PathFollower(Path path, PathFollowerConfig config)
    : path_(std::move(path)),
      config_(config),
      steering_pid_(config.steering),
      speed_pid_(config.speed) {}

vehicle::DriverInputs PathFollower::update(double time_s, const Pose& pose, const Vec3& velocity,
                                           double dt) {
  const Vec3 forward3 = pose.orientation * Vec3::UnitX();
  Vec2 heading(forward3.x(), forward3.y());
  if (heading.norm() < 1e-9) heading = Vec2::UnitX();
  heading.normalize();
  const Vec2 position(pose.position.x(), pose.position.y());

  // Track progress along the path (windowed search keeps self-crossing paths unambiguous).
  const PathPoint here = path_.closest(position, progress_s_);
  progress_s_ = here.s;
  lateral_error_ = here.lateral_error;

  // Steering: signed distance from the sentinel to the path point closest to it.
  const Vec2 sentinel = position + config_.lookahead_m * heading;
  const PathPoint target = path_.closest(sentinel, progress_s_ + config_.lookahead_m);
  const Vec2 to_target = target.position - sentinel;
  const double cross = heading.x() * to_target.y() - heading.y() * to_target.x();
  const double error = std::copysign(to_target.norm(), cross);
  const double steering = std::clamp(steering_pid_.update(error, dt), -1.0, 1.0);

  // Speed: profile, tapered so that an open path ends at rest.
  target_speed_ = config_.speed_profile.at(time_s);
  if (!path_.closed()) {
    const double remaining = std::max(0.0, path_.length() - progress_s_);
    target_speed_ = std::min(target_speed_, std::sqrt(2.0 * config_.stop_decel_mps2 * remaining));
    if (remaining < 0.5) target_speed_ = 0.0;
  }
  const double speed = velocity.x() * heading.x() + velocity.y() * heading.y();
  const double out = speed_pid_.update(target_speed_ - speed, dt);

  vehicle::DriverInputs cmd;
  cmd.steering = steering;
  cmd.throttle = out > 0.0 ? std::min(out, 1.0) : 0.0;
  cmd.braking = out < 0.0 ? std::min(-out, 1.0) : 0.0;
  if (target_speed_ == 0.0 && std::abs(speed) < 0.5) {
    cmd.throttle = 0.0;
    cmd.braking = 1.0;  // hold the vehicle at the end of the path
  }
  return cmd;
}

}  // namespace syndds::control

namespace syndds::control {

template <typename Archive>
void PathFollower::state_io(Archive& a) {
  a.begin("path_follower", 1);
  steering_pid_.state_io(a);
  speed_pid_.state_io(a);
  a.io(progress_s_);
  a.io(target_speed_);
  a.io(lateral_error_);
  a.end();
}

void PathFollower::save_state(core::StateWriter& w) const {
  const_cast<PathFollower*>(this)->state_io(w);  // the writer only reads
}

void PathFollower::load_state(core::StateReader& r) { state_io(r); }

}  // namespace syndds::control
