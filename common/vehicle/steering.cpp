#include "vehicle/steering.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace syndds::vehicle {

double rear_axle_turn_radius_m(const VehicleParams& p, double steering) {
  const double inner = std::abs(steering) * deg_to_rad(p.steering.max_angle_deg);
  if (inner <= 0.0) return std::numeric_limits<double>::infinity();
  const double r = p.wheelbase_m() / std::tan(inner) + p.front.half_track_m;
  return steering > 0 ? r : -r;
}

AckermannAngles ackermann_angles(const VehicleParams& p, double steering) {
  if (steering == 0.0) return {};
  const double r = std::abs(rear_axle_turn_radius_m(p, steering));
  const double inner = std::abs(steering) * deg_to_rad(p.steering.max_angle_deg);
  const double outer = std::atan(p.wheelbase_m() / (r + p.front.half_track_m));
  if (steering > 0) return {inner, outer};  // left turn: the left wheel is inside
  return {-outer, -inner};
}

double steering_for_rear_axle_radius(const VehicleParams& p, double radius_m) {
  const double r = std::abs(radius_m);
  const double inner_arm = r - p.front.half_track_m;
  if (inner_arm <= 0.0) throw std::invalid_argument("turn radius below the half track");
  const double inner = std::atan(p.wheelbase_m() / inner_arm);
  const double s = inner / deg_to_rad(p.steering.max_angle_deg);
  if (s > 1.0 + 1e-12) throw std::invalid_argument("turn radius below the minimum");
  return radius_m > 0 ? s : -s;
}

}  // namespace syndds::vehicle
