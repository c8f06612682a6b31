#pragma once
// A smooth planar path: a centripetal Catmull-Rom spline through the waypoints, sampled into
// a dense polyline with arc length, so that closest-point and point-at-distance queries are
// cheap and exact on the polyline.
#include <vector>

#include "core/math.hpp"

namespace syndds::control {

struct PathPoint {
  Vec2 position = Vec2::Zero();
  Vec2 tangent = Vec2::UnitX();  // unit
  double s = 0.0;                // arc length from the start
  double lateral_error = 0.0;    // signed: positive when the query point is left of the path
};

class Path {
 public:
  /// At least two distinct waypoints. `closed` joins the last waypoint back to the first.
  Path(std::vector<Vec2> waypoints, bool closed, double sample_spacing_m = 0.2);

  double length() const { return s_.back(); }
  bool closed() const { return closed_; }
  const std::vector<Vec2>& samples() const { return points_; }
  const std::vector<Vec2>& waypoints() const { return waypoints_; }

  /// Point at arc length s (wrapped for closed paths, clamped otherwise).
  PathPoint at(double s) const;
  /// Closest point on the path to p. With `near_s`, only the stretch within `window_m` of it is
  /// searched (keeps self-crossing paths unambiguous).
  PathPoint closest(const Vec2& p, double near_s = -1.0, double window_m = 30.0) const;

 private:
  /// The point of segment i nearest to p, and its parameter u in [0, 1] along the segment.
  Vec2 foot_point(std::size_t i, const Vec2& p, double& u) const;
  PathPoint on_segment(std::size_t i, const Vec2& p) const;
  std::vector<Vec2> waypoints_;
  bool closed_;
  std::vector<Vec2> points_;
  std::vector<double> s_;
};

}  // namespace syndds::control
