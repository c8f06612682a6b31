#pragma once
// Oriented rectangles in the ground plane: the broad phase of vehicle-vehicle contact, the
// reduced model's contact and the bumper gap of the convoy report. Header-only, exact
// (separating axis theorem), no allocation.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "core/math.hpp"

namespace syndds {

struct Rect2 {
  Vec2 centre = Vec2::Zero();
  double yaw = 0.0;          // direction of the first half extent, counter-clockwise from x
  double half_length = 0.0;  // along yaw
  double half_width = 0.0;   // across

  Vec2 axis_x() const { return {std::cos(yaw), std::sin(yaw)}; }
  Vec2 axis_y() const { return {-std::sin(yaw), std::cos(yaw)}; }
  std::array<Vec2, 4> corners() const {
    const Vec2 ex = half_length * axis_x();
    const Vec2 ey = half_width * axis_y();
    return {centre + ex + ey, centre - ex + ey, centre - ex - ey, centre + ex - ey};
  }
  /// Half the rectangle's extent along the unit vector `n`.
  double radius_along(const Vec2& n) const {
    return half_length * std::abs(n.dot(axis_x())) + half_width * std::abs(n.dot(axis_y()));
  }
};

/// Separating-axis result of two rectangles: `depth` > 0 is the smallest overlap (the
/// penetration), along `normal` (unit, pointing from a to b); depth <= 0 is minus the largest
/// separation found along the four axes (a lower bound of the distance, 0 when touching).
struct RectOverlap {
  double depth = 0.0;
  Vec2 normal = Vec2::UnitX();
};

inline RectOverlap rect_overlap(const Rect2& a, const Rect2& b) {
  const Vec2 d = b.centre - a.centre;
  RectOverlap best;
  best.depth = std::numeric_limits<double>::infinity();
  for (const Vec2& axis : {a.axis_x(), a.axis_y(), b.axis_x(), b.axis_y()}) {
    const double centre_distance = d.dot(axis);
    const double overlap = a.radius_along(axis) + b.radius_along(axis) - std::abs(centre_distance);
    if (overlap < best.depth) {
      best.depth = overlap;
      best.normal = centre_distance >= 0.0 ? axis : Vec2(-axis);
    }
  }
  return best;
}

/// True if the rectangles come within `margin` of each other (or overlap). Conservative in the
/// corner regions (an axis test): it may say yes for rectangles up to margin * sqrt(2) apart.
inline bool rects_within(const Rect2& a, const Rect2& b, double margin) {
  return rect_overlap(a, b).depth > -margin;
}

/// Distance from point p to segment [s0, s1].
inline double point_segment_distance(const Vec2& p, const Vec2& s0, const Vec2& s1) {
  const Vec2 s = s1 - s0;
  const double len2 = s.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - s0).dot(s) / len2, 0.0, 1.0) : 0.0;
  return (p - (s0 + t * s)).norm();
}

/// Exact distance between two rectangles (0 if they touch or overlap).
inline double rect_distance(const Rect2& a, const Rect2& b) {
  if (rect_overlap(a, b).depth >= 0.0) return 0.0;
  const auto ca = a.corners();
  const auto cb = b.corners();
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      best = std::min(best, point_segment_distance(ca[i], cb[j], cb[(j + 1) % 4]));
      best = std::min(best, point_segment_distance(cb[j], ca[i], ca[(i + 1) % 4]));
    }
  }
  return best;
}

}  // namespace syndds
