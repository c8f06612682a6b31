#include <algorithm>
#include <cmath>

#include "vehicle/vehicle_model.hpp"

namespace syndds::vehicle {

Footprint footprint_of(const VehicleParams& p) {
  const Vec3& he = p.chassis.half_extents_m;
  const Vec3& bc = p.chassis.box_centre_m;
  double x_min = bc.x() - he.x(), x_max = bc.x() + he.x();
  double y_max = std::abs(bc.y()) + he.y();
  // A wheel turned any way stays within this distance of its centre in the ground plane.
  const double wheel_reach = std::hypot(p.wheels.radius_m, 0.5 * p.wheels.width_m);
  for (const AxleParams* a : {&p.front, &p.rear}) {
    x_min = std::min(x_min, a->x_m - wheel_reach);
    x_max = std::max(x_max, a->x_m + wheel_reach);
    y_max = std::max(y_max, a->half_track_m + wheel_reach);
  }
  return Footprint{0.5 * (x_min + x_max), 0.5 * (x_max - x_min), y_max};
}

}  // namespace syndds::vehicle
