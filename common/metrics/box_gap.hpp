#pragma once
// Distance between two vehicles' bodies: the smallest distance between their chassis boxes
// (VehicleParams::chassis half_extents_m and box_centre_m, placed by each vehicle's pose). For
// two vehicles one behind the other it is the bumper-to-bumper gap; for any other placement it
// is still the clearance between the boxes. Boxes that touch or overlap are 0 apart.
//
// Exact for boxes (convex polyhedra): when they are apart, a closest pair of points has a vertex
// of one box on one side, or lies on an edge of each. So the distance is the smallest of: every
// vertex of one box to the other box (closed form in that box's frame), and every edge of one to
// every edge of the other (segment to segment). Overlap is decided by the separating-axis test
// (the 3 face normals of each box and the 9 cross products of their edges).
#include "core/math.hpp"

namespace syndds::metrics {

/// A box: `centre` and `orientation` in the world, `half_extents` along its own axes.
struct OrientedBox {
  Vec3 centre = Vec3::Zero();
  Quat orientation = Quat::Identity();
  Vec3 half_extents = Vec3::Zero();
};

/// The box of a body whose box is `half_extents` around `box_centre` (in the body frame),
/// for the body at `pose`.
OrientedBox place_box(const Pose& pose, const Vec3& box_centre, const Vec3& half_extents);

/// True when the boxes overlap or touch.
bool boxes_overlap(const OrientedBox& a, const OrientedBox& b);

/// Smallest distance between the two boxes (solids): 0 when they overlap or touch.
double box_distance(const OrientedBox& a, const OrientedBox& b);

}  // namespace syndds::metrics
