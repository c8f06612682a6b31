#include "metrics/box_gap.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace syndds::metrics {
namespace {

using Mat3 = Eigen::Matrix3d;

struct Segment {
  Vec3 a;
  Vec3 b;
};

std::array<Vec3, 8> vertices(const OrientedBox& box, const Mat3& r) {
  std::array<Vec3, 8> v;
  for (int k = 0; k < 8; ++k) {
    const Vec3 sign((k & 1) ? 1.0 : -1.0, (k & 2) ? 1.0 : -1.0, (k & 4) ? 1.0 : -1.0);
    v[k] = box.centre + r * sign.cwiseProduct(box.half_extents);
  }
  return v;
}

// The 12 edges: for each axis, the 4 segments along it through the corners of the other two.
std::array<Segment, 12> edges(const OrientedBox& box, const Mat3& r) {
  std::array<Segment, 12> e;
  int n = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, w = (axis + 2) % 3;
    for (int k = 0; k < 4; ++k) {
      Vec3 offset = Vec3::Zero();
      offset[u] = (k & 1 ? 1.0 : -1.0) * box.half_extents[u];
      offset[w] = (k & 2 ? 1.0 : -1.0) * box.half_extents[w];
      Vec3 along = Vec3::Zero();
      along[axis] = box.half_extents[axis];
      e[n++] = {box.centre + r * (offset - along), box.centre + r * (offset + along)};
    }
  }
  return e;
}

// Distance from a point to a solid box: clamp into the box in its own frame.
double point_box_distance(const Vec3& p, const OrientedBox& box, const Mat3& r) {
  const Vec3 local = r.transpose() * (p - box.centre);
  const Vec3 inside = local.cwiseMax(-box.half_extents).cwiseMin(box.half_extents);
  return (local - inside).norm();
}

// Closest distance between segments p1-q1 and p2-q2 (Ericson, Real-Time Collision Detection,
// 5.1.9), degenerate segments included.
double segment_distance(const Segment& s1, const Segment& s2) {
  constexpr double kEps = 1e-12;
  const Vec3 d1 = s1.b - s1.a, d2 = s2.b - s2.a, r = s1.a - s2.a;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (a <= kEps && e <= kEps) return r.norm();
  if (a <= kEps) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= kEps) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2);
      const double denom = a * e - b * b;
      s = denom > kEps * a * e ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return ((s1.a + s * d1) - (s2.a + t * d2)).norm();
}

}  // namespace

OrientedBox place_box(const Pose& pose, const Vec3& box_centre, const Vec3& half_extents) {
  const Quat q = pose.orientation.normalized();
  return {pose.position + q * box_centre, q, half_extents};
}

bool boxes_overlap(const OrientedBox& a, const OrientedBox& b) {
  // Separating-axis test in a's frame (Ericson 4.4.1); the epsilon keeps the cross products of
  // nearly parallel edges from declaring a separation that is only rounding.
  constexpr double kEps = 1e-9;
  const Mat3 ra = a.orientation.normalized().toRotationMatrix();
  const Mat3 rb = b.orientation.normalized().toRotationMatrix();
  const Mat3 rot = ra.transpose() * rb;
  const Mat3 abs_rot = (rot.cwiseAbs().array() + kEps).matrix();
  const Vec3 t = ra.transpose() * (b.centre - a.centre);
  const Vec3& ea = a.half_extents;
  const Vec3& eb = b.half_extents;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(t[i]) > ea[i] + eb.dot(abs_rot.row(i).transpose())) return false;
  }
  for (int j = 0; j < 3; ++j) {
    if (std::abs(t.dot(rot.col(j))) > ea.dot(abs_rot.col(j)) + eb[j]) return false;
  }
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    for (int j = 0; j < 3; ++j) {
      const int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      const double ra_ = ea[i1] * abs_rot(i2, j) + ea[i2] * abs_rot(i1, j);
      const double rb_ = eb[j1] * abs_rot(i, j2) + eb[j2] * abs_rot(i, j1);
      if (std::abs(t[i2] * rot(i1, j) - t[i1] * rot(i2, j)) > ra_ + rb_) return false;
    }
  }
  return true;
}

double box_distance(const OrientedBox& a, const OrientedBox& b) {
  if (boxes_overlap(a, b)) return 0.0;
  const Mat3 ra = a.orientation.normalized().toRotationMatrix();
  const Mat3 rb = b.orientation.normalized().toRotationMatrix();
  double best = std::numeric_limits<double>::infinity();
  for (const Vec3& v : vertices(a, ra)) best = std::min(best, point_box_distance(v, b, rb));
  for (const Vec3& v : vertices(b, rb)) best = std::min(best, point_box_distance(v, a, ra));
  const auto ea = edges(a, ra);
  const auto eb = edges(b, rb);
  for (const auto& s1 : ea) {
    for (const auto& s2 : eb) best = std::min(best, segment_distance(s1, s2));
  }
  return best;
}

}  // namespace syndds::metrics
