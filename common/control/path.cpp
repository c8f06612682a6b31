#include "control/path.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

namespace syndds::control {
namespace {

// Centripetal Catmull-Rom between p1 and p2 (alpha = 0.5), parameter u in [0, 1].
Vec2 catmull_rom(const Vec2& p0, const Vec2& p1, const Vec2& p2, const Vec2& p3, double u) {
  auto knot = [](double t, const Vec2& a, const Vec2& b) {
    return t + std::max(std::sqrt((b - a).norm()), 1e-6);
  };
  const double t0 = 0.0;
  const double t1 = knot(t0, p0, p1);
  const double t2 = knot(t1, p1, p2);
  const double t3 = knot(t2, p2, p3);
  const double t = t1 + u * (t2 - t1);
  const Vec2 a1 = (t1 - t) / (t1 - t0) * p0 + (t - t0) / (t1 - t0) * p1;
  const Vec2 a2 = (t2 - t) / (t2 - t1) * p1 + (t - t1) / (t2 - t1) * p2;
  const Vec2 a3 = (t3 - t) / (t3 - t2) * p2 + (t - t2) / (t3 - t2) * p3;
  const Vec2 b1 = (t2 - t) / (t2 - t0) * a1 + (t - t0) / (t2 - t0) * a2;
  const Vec2 b2 = (t3 - t) / (t3 - t1) * a2 + (t - t1) / (t3 - t1) * a3;
  return (t2 - t) / (t2 - t1) * b1 + (t - t1) / (t2 - t1) * b2;
}

}  // namespace

Path::Path(std::vector<Vec2> waypoints, bool closed, double sample_spacing_m)
    : waypoints_(std::move(waypoints)), closed_(closed) {
  // Drop consecutive duplicates.
  std::vector<Vec2> w;
  for (const auto& p : waypoints_) {
    if (w.empty() || (p - w.back()).norm() > 1e-6) w.push_back(p);
  }
  if (closed_ && w.size() > 1 && (w.front() - w.back()).norm() < 1e-6) w.pop_back();
  if (w.size() < 2) throw std::invalid_argument("a path needs at least two distinct waypoints");

  const std::size_t n = w.size();
  const std::size_t segments = closed_ ? n : n - 1;
  auto get = [&](long i) -> Vec2 {
    if (closed_) return w[static_cast<std::size_t>((i % static_cast<long>(n) + n) % n)];
    if (i < 0) return 2.0 * w[0] - w[1];  // reflected end points keep the ends straight
    if (i >= static_cast<long>(n)) return 2.0 * w[n - 1] - w[n - 2];
    return w[static_cast<std::size_t>(i)];
  };
  points_.push_back(w[0]);
  for (std::size_t k = 0; k < segments; ++k) {
    const long i = static_cast<long>(k);
    const Vec2 p0 = get(i - 1), p1 = get(i), p2 = get(i + 1), p3 = get(i + 2);
    const int steps = std::max(1, static_cast<int>(std::ceil((p2 - p1).norm() / sample_spacing_m)));
    for (int j = 1; j <= steps; ++j) {
      points_.push_back(catmull_rom(p0, p1, p2, p3, static_cast<double>(j) / steps));
    }
  }
  s_.assign(points_.size(), 0.0);
  for (std::size_t i = 1; i < points_.size(); ++i) {
    s_[i] = s_[i - 1] + (points_[i] - points_[i - 1]).norm();
  }
}

Vec2 Path::foot_point(std::size_t i, const Vec2& p, double& u) const {
  const Vec2& a = points_[i];
  const Vec2 d = points_[i + 1] - a;
  const double len2 = d.squaredNorm();
  u = len2 > 0.0 ? std::clamp((p - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  return a + u * d;
}

PathPoint Path::on_segment(std::size_t i, const Vec2& p) const {
  double u = 0.0;
  PathPoint out;
  out.position = foot_point(i, p, u);
  const Vec2 d = points_[i + 1] - points_[i];
  const double len2 = d.squaredNorm();
  out.tangent = len2 > 0.0 ? Vec2(d / std::sqrt(len2)) : Vec2::UnitX();
  out.s = s_[i] + u * (s_[i + 1] - s_[i]);
  const Vec2 r = p - out.position;
  out.lateral_error = out.tangent.x() * r.y() - out.tangent.y() * r.x();
  return out;
}

PathPoint Path::at(double s) const {
  if (closed_) {
    s = std::fmod(s, length());
    if (s < 0) s += length();
  } else {
    s = std::clamp(s, 0.0, length());
  }
  auto it = std::upper_bound(s_.begin(), s_.end(), s);
  std::size_t i = it == s_.begin() ? 0 : static_cast<std::size_t>(it - s_.begin()) - 1;
  i = std::min(i, points_.size() - 2);
  const double seg = s_[i + 1] - s_[i];
  const double u = seg > 0 ? (s - s_[i]) / seg : 0.0;
  PathPoint out;
  out.position = points_[i] + u * (points_[i + 1] - points_[i]);
  out.tangent = (points_[i + 1] - points_[i]).normalized();
  out.s = s;
  return out;
}

PathPoint Path::closest(const Vec2& p, double near_s, double window_m) const {
  PathPoint best;
  double best_d2 = std::numeric_limits<double>::infinity();
  const std::size_t segments = points_.size() - 1;
  // Segment i is searched when either of its ends lies within the window of near_s (for a
  // closed path, the distance of its start is also taken the other way round). The arc
  // lengths are sorted, so only the index ranges that can pass are visited; a slack far above
  // rounding keeps them a superset, and the exact test below decides, in index order, as a
  // scan of every segment would.
  std::array<std::pair<std::size_t, std::size_t>, 3> ranges{};  // [first, last) of segments
  std::size_t n_ranges = 0;
  if (near_s < 0.0) {
    ranges[n_ranges++] = {0, segments};
  } else {
    const double slack = 1e-6 * (1.0 + std::abs(near_s) + length() + window_m);
    auto first_at = [&](double s) {  // first sample with s_ >= s
      return static_cast<std::size_t>(std::lower_bound(s_.begin(), s_.end(), s) - s_.begin());
    };
    auto range = [&](double lo, double hi) {  // segments with an end in [lo, hi]
      const std::size_t a = first_at(lo);
      const std::size_t b = first_at(hi);  // samples [a, b] may lie in it (b: rounding)
      ranges[n_ranges++] = {a == 0 ? 0 : a - 1, std::min(segments, b + 1)};
    };
    range(near_s - window_m - slack, near_s + window_m + slack);
    if (closed_) {  // min(d, length - d) <= window for d far the other way
      range(-std::numeric_limits<double>::infinity(), near_s - length() + window_m + slack);
      range(near_s + length() - window_m - slack, std::numeric_limits<double>::infinity());
    }
    for (std::size_t r = 1; r < n_ranges; ++r) {  // order by first index (at most three)
      for (std::size_t q = r; q > 0 && ranges[q] < ranges[q - 1]; --q) {
        std::swap(ranges[q], ranges[q - 1]);
      }
    }
  }
  std::size_t next = 0;  // ranges overlap: visit each segment once, in index order
  std::size_t best_i = segments;
  for (std::size_t r = 0; r < n_ranges; ++r) {
    const auto [first, last] = ranges[r];
    for (std::size_t i = std::max(first, next); i < last; ++i) {
      if (near_s >= 0.0) {
        double ds = std::abs(s_[i] - near_s);
        if (closed_) ds = std::min(ds, length() - ds);
        if (ds > window_m && std::abs(s_[i + 1] - near_s) > window_m) continue;
      }
      // The foot point only; the tangent, arc length and lateral error (on_segment, from the
      // same foot point) only for the segment that wins.
      double u = 0.0;
      const double d2 = (foot_point(i, p, u) - p).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best_i = i;
      }
    }
    next = std::max(next, last);
  }
  if (!std::isfinite(best_d2)) return closest(p);  // window empty: search everything
  return on_segment(best_i, p);
}

}  // namespace syndds::control
