#pragma once
// Ackermann steering geometry of the front axle. The steering input s in [-1, 1] (positive
// turns left) sets the inner road-wheel angle |s| * max_angle; the outer wheel points at the
// same turn centre on the rear-axle line:  R = L / tan(inner) + t/2  (rear-axle centre),
// tan(outer) = L / (R + t/2).  The equivalent bicycle angle is atan(L / R).
#include "vehicle/vehicle_params.hpp"

namespace syndds::vehicle {

struct AckermannAngles {
  double left_rad = 0.0;   // positive = wheel turned left
  double right_rad = 0.0;
};

/// Road-wheel angles of the front wheels for a normalized steering input.
AckermannAngles ackermann_angles(const VehicleParams& params, double steering);
/// Signed turn radius at the rear-axle centre (positive: left turn; infinite at 0).
double rear_axle_turn_radius_m(const VehicleParams& params, double steering);
/// Steering input whose kinematic turn radius at the rear-axle centre is `radius_m` (> 0:
/// left). Throws std::invalid_argument if the radius is below the minimum.
double steering_for_rear_axle_radius(const VehicleParams& params, double radius_m);

}  // namespace syndds::vehicle
