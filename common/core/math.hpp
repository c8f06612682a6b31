#pragma once
// Geometry helpers over Eigen. World frame: x east, y north, z up (ENU), right-handed;
// vehicle frame: x forward, y left, z up. Angles in radians unless a name says _deg.
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace syndds {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Quat = Eigen::Quaterniond;

struct Pose {
  Vec3 position = Vec3::Zero();
  Quat orientation = Quat::Identity();
};

constexpr double kGravity = 9.80665;

inline double deg_to_rad(double deg) { return deg * std::numbers::pi / 180.0; }
inline double rad_to_deg(double rad) { return rad * 180.0 / std::numbers::pi; }

/// Wraps an angle to (-pi, pi].
inline double wrap_angle(double a) {
  a = std::fmod(a + std::numbers::pi, 2.0 * std::numbers::pi);
  if (a <= 0.0) a += 2.0 * std::numbers::pi;
  return a - std::numbers::pi;
}

inline Quat quat_from_yaw(double yaw) { return Quat(Eigen::AngleAxisd(yaw, Vec3::UnitZ())); }

/// Heading (yaw) of the body x axis projected on the horizontal plane.
inline double yaw_of(const Quat& q) {
  const Vec3 forward = q * Vec3::UnitX();
  return std::atan2(forward.y(), forward.x());
}

inline double clamp(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

}  // namespace syndds
