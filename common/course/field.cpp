#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/hash.hpp"
#include "course/course.hpp"

namespace syndds::course {

namespace {

bool overlap_ok(const Circle& a, const Circle& b, double fraction) {
  const double min_distance =
      a.radius + b.radius - fraction * std::min(a.radius, b.radius);
  return (a.centre - b.centre).norm() >= min_distance;
}

}  // namespace

Rng::Rng(std::uint64_t seed, std::uint64_t stream)
    : engine_(splitmix64(splitmix64(seed) ^ splitmix64(~stream))) {}

Field generate_field(std::uint64_t seed, int draw, const FieldParams& p) {
  Field field;
  field.params = p;
  field.start = Vec2(0.0, 0.0);
  field.goal = Vec2(p.size_m, p.size_m);
  for (int i = 1; i <= p.fixed_count; ++i) {
    const double t = p.size_m * i / (p.fixed_count + 1);
    field.obstacles.push_back({Vec2(t, t), p.fixed_radius_m});
  }
  // Streams 0, 1, 2, ... are the field draws; the planner uses streams from 2^32 up.
  Rng rng(seed, static_cast<std::uint64_t>(draw));
  for (int k = 0; k < p.random_count; ++k) {
    bool placed = false;
    for (int attempt = 0; attempt < p.attempts_per_obstacle && !placed; ++attempt) {
      Circle c;
      c.centre.x() = rng.uniform(0.0, p.size_m);
      c.centre.y() = rng.uniform(0.0, p.size_m);
      c.radius = rng.uniform(p.radius_min_m, p.radius_max_m);
      if ((c.centre - field.start).norm() < c.radius + p.keep_out_m) continue;
      if ((c.centre - field.goal).norm() < c.radius + p.keep_out_m) continue;
      placed = std::all_of(field.obstacles.begin(), field.obstacles.end(),
                           [&](const Circle& o) { return overlap_ok(c, o, p.overlap_fraction); });
      if (placed) field.obstacles.push_back(c);
    }
    if (!placed) {
      throw CourseError("course field seed " + std::to_string(seed) + " draw " +
                        std::to_string(draw) + ": obstacle " + std::to_string(k + 1) +
                        " not placed in " + std::to_string(p.attempts_per_obstacle) +
                        " attempts");
    }
  }
  return field;
}

std::vector<std::string> field_violations(const Field& f) {
  const FieldParams& p = f.params;
  std::vector<std::string> out;
  auto fail = [&](std::size_t i, const std::string& what) {
    std::ostringstream s;
    s << "obstacle " << i << " at (" << f.obstacles[i].centre.x() << ", "
      << f.obstacles[i].centre.y() << ") r " << f.obstacles[i].radius << ": " << what;
    out.push_back(s.str());
  };
  const std::size_t expected = static_cast<std::size_t>(p.fixed_count + p.random_count);
  if (f.obstacles.size() != expected) {
    out.push_back("obstacle count " + std::to_string(f.obstacles.size()) + " != " +
                  std::to_string(expected));
  }
  for (std::size_t i = 0; i < f.obstacles.size(); ++i) {
    const Circle& c = f.obstacles[i];
    const bool fixed = i < static_cast<std::size_t>(p.fixed_count);
    if (fixed) {
      const double t = p.size_m * static_cast<double>(i + 1) / (p.fixed_count + 1);
      if ((c.centre - Vec2(t, t)).norm() > 1e-12 || c.radius != p.fixed_radius_m) {
        fail(i, "fixed obstacle not on the diagonal at fraction " + std::to_string(i + 1) +
                    "/" + std::to_string(p.fixed_count + 1));
      }
    } else {
      if (c.radius < p.radius_min_m || c.radius > p.radius_max_m) fail(i, "radius out of range");
      if (c.centre.x() < 0 || c.centre.x() > p.size_m || c.centre.y() < 0 ||
          c.centre.y() > p.size_m) {
        fail(i, "centre outside the field");
      }
      if ((c.centre - f.start).norm() < c.radius + p.keep_out_m) fail(i, "in the start keep-out");
      if ((c.centre - f.goal).norm() < c.radius + p.keep_out_m) fail(i, "in the goal keep-out");
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (!overlap_ok(c, f.obstacles[j], p.overlap_fraction)) {
        fail(i, "overlaps obstacle " + std::to_string(j) + " by more than the allowed fraction");
      }
    }
  }
  return out;
}

}  // namespace syndds::course
