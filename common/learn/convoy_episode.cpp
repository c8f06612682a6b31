#include "learn/convoy_episode.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>

#include "core/text.hpp"
#include "course/course.hpp"

namespace syndds::learn {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kCentre = 0.5 * kConvoyAreaM;

// [0, 1) from 53 random bits: the same numbers on every standard library.
double unit(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// The canonical shapes inside [10, 80] x [10, 80] (obstacles up to 10 m aside stay in the area).
std::vector<Vec2> s_shape() {
  // x = 10 + 70 t, y = 10 + 70 (3 t^2 - 2 t^3): leaves heading east, bends left, then right,
  // arrives heading east at the opposite corner; the steepest stretch is 56 degrees.
  std::vector<Vec2> fine;
  for (int i = 0; i <= 2000; ++i) {
    const double t = i / 2000.0;
    fine.emplace_back(10.0 + 70.0 * t, 10.0 + 70.0 * (3.0 * t * t - 2.0 * t * t * t));
  }
  return fine;
}

std::vector<Vec2> c_shape() {
  std::vector<Vec2> fine;
  for (int i = 0; i <= 400; ++i) fine.emplace_back(10.0 + 40.0 * i / 400.0, 15.0);  // east
  for (int i = 1; i <= 1200; ++i) {  // half circle of 30 m about (50, 45), anticlockwise
    const double a = -0.5 * kPi + kPi * i / 1200.0;
    fine.emplace_back(50.0 + 30.0 * std::cos(a), 45.0 + 30.0 * std::sin(a));
  }
  for (int i = 1; i <= 400; ++i) fine.emplace_back(50.0 - 40.0 * i / 400.0, 75.0);  // west
  return fine;
}

// Resamples a finely drawn polyline at whole metres of arc length (plus its end point).
std::vector<Vec2> resample(const std::vector<Vec2>& fine, double spacing) {
  std::vector<Vec2> out{fine.front()};
  double acc = 0.0, next = spacing;
  for (std::size_t i = 1; i < fine.size(); ++i) {
    const double d = (fine[i] - fine[i - 1]).norm();
    while (acc + d >= next) {
      out.push_back(fine[i - 1] + (next - acc) / d * (fine[i] - fine[i - 1]));
      next += spacing;
    }
    acc += d;
  }
  if ((out.back() - fine.back()).norm() > 0.25 * spacing) out.push_back(fine.back());
  else out.back() = fine.back();
  return out;
}

double length(const std::vector<Vec2>& p) {
  double l = 0.0;
  for (std::size_t i = 1; i < p.size(); ++i) l += (p[i] - p[i - 1]).norm();
  return l;
}

// Point and unit tangent at arc length s.
void at_arc(const std::vector<Vec2>& p, double s, Vec2& point, Vec2& tangent) {
  double acc = 0.0;
  for (std::size_t i = 1; i < p.size(); ++i) {
    const double d = (p[i] - p[i - 1]).norm();
    if (acc + d >= s || i + 1 == p.size()) {
      tangent = (p[i] - p[i - 1]) / d;
      point = p[i - 1] + std::clamp(s - acc, 0.0, d) * tangent;
      return;
    }
    acc += d;
  }
  throw std::logic_error("at_arc: a path of fewer than two points");
}

std::string num(double v) { return trimmed_decimal(v, 4); }

}  // namespace

PathVariant PathVariant::from_index(int v) {
  if (v < 0 || v >= kConvoyPathVariants) {
    throw std::invalid_argument("convoy path variant " + std::to_string(v) + ": expected 0..15");
  }
  return {(v & 1) != 0, (v & 2) != 0, (v & 4) != 0, (v & 8) != 0};
}

std::vector<Vec2> convoy_path(int variant) {
  const PathVariant pv = PathVariant::from_index(variant);
  std::vector<Vec2> p = resample(pv.c_shape ? c_shape() : s_shape(), 1.0);
  for (Vec2& q : p) {
    if (pv.mirror_east_west) q.x() = kConvoyAreaM - q.x();
    if (pv.mirror_north_south) q.y() = kConvoyAreaM - q.y();
    if (pv.rotated) q = Vec2(kCentre - (q.y() - kCentre), kCentre + (q.x() - kCentre));
  }
  return p;
}

double distance_to_path(const std::vector<Vec2>& path, const Vec2& p) {
  double best = (p - path.front()).norm();
  for (std::size_t i = 1; i < path.size(); ++i) {
    const Vec2 a = path[i - 1], ab = path[i] - a;
    const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (p - (a + t * ab)).norm());
  }
  return best;
}

ConvoyEpisodeKind parse_episode_kind(const std::string& name) {
  if (name == "paper") return ConvoyEpisodeKind::paper;
  if (name == "courses") return ConvoyEpisodeKind::courses;
  if (name == "mixed") return ConvoyEpisodeKind::mixed;
  throw std::invalid_argument("episodes '" + name + "' is not one of paper, courses, mixed");
}

namespace {

// Courses take about 0.2 s each to plan: every one is made once per process and shared by
// the environment copies (a course is a pure function of its seed).
const course::Course& training_course(std::uint64_t seed) {
  static std::mutex mutex;
  static std::map<std::uint64_t, course::Course> cache;
  const std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(seed);
  if (it == cache.end()) {
    // A seed whose fields give no path in 20 draws stands for the next that does (seed +
    // kTrainingCourses, + 2 kTrainingCourses, ...: seeds no other training episode uses).
    for (std::uint64_t s = seed;; s += kTrainingCourses) {
      try {
        it = cache.emplace(seed, course::make_course(s)).first;
        break;
      } catch (const course::CourseError&) {
        if (s > seed + 100 * kTrainingCourses) throw;
      }
    }
  }
  return it->second;
}

// The path from arc length `arc` to the end: the point there, then the path's points beyond
// it (at least 0.5 m on, so that no two waypoints coincide).
std::vector<Vec2> path_from(const std::vector<Vec2>& path, double arc, const Vec2& start) {
  std::vector<Vec2> out{start};
  double acc = 0.0;
  for (std::size_t i = 1; i < path.size(); ++i) {
    acc += (path[i] - path[i - 1]).norm();
    if (acc > arc + 0.5) out.push_back(path[i]);
  }
  return out;
}

// The leader's start (gap_m ahead of the follower) and its path from there to the end.
void place_pair(ConvoyEpisode& e, const ConvoyEpisodeOptions& o) {
  e.leader_arc_m = e.follower_arc_m + o.gap_m;
  Vec2 t;
  at_arc(e.path, e.follower_arc_m, e.follower_start, t);
  e.follower_yaw_rad = std::atan2(t.y(), t.x());
  at_arc(e.path, e.leader_arc_m, e.leader_start, t);
  e.leader_yaw_rad = std::atan2(t.y(), t.x());
  e.leader_path = path_from(e.path, e.leader_arc_m, e.leader_start);
  if (e.leader_path.size() < 2) throw std::logic_error("convoy episode: leader starts at the end");
}

// A head vehicle gap_m ahead of the leader (ConvoyEpisodeOptions::chain_fraction), drawn from
// a stream of its own; not where fewer than 20 m of path would be left to it.
void chain_leader(ConvoyEpisode& e, std::uint64_t seed, const ConvoyEpisodeOptions& o) {
  if (o.chain_fraction <= 0.0) return;
  std::mt19937_64 rng(seed ^ 0x7f4a7c159e3779b9ULL);
  if (unit(rng) >= o.chain_fraction) return;
  const double head_arc = e.leader_arc_m + o.gap_m;
  if (head_arc + 20.0 > e.path_length_m) return;
  e.chained = true;
  e.head_arc_m = head_arc;
  Vec2 t;
  at_arc(e.path, head_arc, e.head_start, t);
  e.head_yaw_rad = std::atan2(t.y(), t.x());
  e.head_path = path_from(e.path, head_arc, e.head_start);
}

// The leader's path displaced sideways by the drawn sine (ConvoyEpisodeOptions).
void wobble_leader(ConvoyEpisode& e, std::uint64_t seed, const ConvoyEpisodeOptions& o) {
  if (o.leader_wobble_m <= 0.0) return;
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  const double wavelength = 8.0 + unit(rng) * 22.0;
  const double k = 2.0 * std::numbers::pi / wavelength;
  const double amplitude =
      std::min(unit(rng) * o.leader_wobble_m, o.leader_wobble_curvature_per_m / (k * k));
  const double phase = unit(rng) * 2.0 * std::numbers::pi;
  const std::vector<Vec2> fine = resample(e.leader_path, 0.5);
  std::vector<Vec2> out{fine.front()};
  for (std::size_t i = 1; i < fine.size(); ++i) {
    const double s = 0.5 * static_cast<double>(i);
    const Vec2 d = (fine[std::min(i + 1, fine.size() - 1)] - fine[i - 1]).normalized();
    const double side = amplitude * std::min(1.0, s / 10.0) * std::sin(k * s + phase);
    out.push_back(fine[i] + side * Vec2(-d.y(), d.x()));
  }
  e.leader_path = std::move(out);
  e.leader_wobble_m = amplitude;
}

// A random obstacle course of the study's generator (current protocol): its planned path and
// its obstacles as the study's scenarios place them (fixed ones rocks, the others trees and
// bushes in turn), the pair starting anywhere in the first 60 % of the path.
ConvoyEpisode course_episode(std::uint64_t seed, const ConvoyEpisodeOptions& o) {
  std::mt19937_64 rng(seed);
  ConvoyEpisode e;
  e.variant = -1;
  e.course_seed = kTrainingCourseSeed + seed % kTrainingCourses;
  const course::Course& c = training_course(e.course_seed);
  e.path = resample(c.path.waypoints, 1.0);
  e.path_length_m = length(e.path);
  e.follower_arc_m = unit(rng) * 0.6 * e.path_length_m;
  place_pair(e, o);
  e.world_min = Vec2(-35.0, -35.0);
  e.world_max = Vec2(135.0, 135.0);
  const int fixed = c.field.params.fixed_count;
  for (std::size_t i = 0; i < c.placed.size(); ++i) {
    const course::Circle& ci = c.placed[i];
    if (ci.radius == 0.0) continue;
    const bool is_fixed = static_cast<int>(i) < fixed;
    const char* label = is_fixed ? "rock" : (i % 2 == 0 ? "tree" : "bush");
    const double height = is_fixed ? 3.0 : (i % 2 == 0 ? 6.0 : 1.5);
    e.obstacles.push_back({std::string(label) + std::to_string(i + 1), label, ci.centre,
                           ci.radius, height});
  }
  wobble_leader(e, seed, o);
  chain_leader(e, seed, o);
  return e;
}

}  // namespace

ConvoyEpisode make_convoy_episode(std::uint64_t seed, const ConvoyEpisodeOptions& o) {
  if (o.kind == ConvoyEpisodeKind::courses || (o.kind == ConvoyEpisodeKind::mixed && seed % 2 == 1)) {
    return course_episode(seed, o);
  }
  std::mt19937_64 rng(seed);
  ConvoyEpisode e;
  e.variant = static_cast<int>(unit(rng) * kConvoyPathVariants);
  e.path = convoy_path(e.variant);
  e.path_length_m = length(e.path);
  e.follower_arc_m = unit(rng) * 0.5 * e.path_length_m;
  place_pair(e, o);

  // Obstacles: rocks, trees and bushes in turn (the kinds of the convoy scenarios), each
  // beside the stretch ahead of the follower, at a drawn side and offset, redrawn until it
  // keeps the path and the other obstacles clear and stays in the area.
  struct Kind {
    const char* label;
    double radius, height;
  };
  static constexpr Kind kKinds[] = {{"rock", 0.8, 3.0}, {"tree", 0.4, 6.0}, {"bush", 1.0, 1.5}};
  for (int k = 0; k < o.obstacles; ++k) {
    const Kind& kind = kKinds[k % 3];
    bool placed = false;
    for (int draw = 0; draw < 1000 && !placed; ++draw) {
      const double s = e.follower_arc_m + 5.0 +
                       unit(rng) * (e.path_length_m - e.follower_arc_m - 5.0);
      const double side = unit(rng) < 0.5 ? -1.0 : 1.0;
      const double offset =
          o.obstacle_offset_min_m + unit(rng) * (o.obstacle_offset_max_m - o.obstacle_offset_min_m);
      Vec2 p, tan;
      at_arc(e.path, s, p, tan);
      const Vec2 c = p + side * offset * Vec2(-tan.y(), tan.x());
      if (c.x() < kind.radius || c.y() < kind.radius || c.x() > kConvoyAreaM - kind.radius ||
          c.y() > kConvoyAreaM - kind.radius) {
        continue;
      }
      if (distance_to_path(e.path, c) - kind.radius < o.clearance_m) continue;
      bool apart = true;
      for (const auto& other : e.obstacles) {
        apart = apart && (other.centre - c).norm() > other.radius_m + kind.radius + 1.0;
      }
      if (!apart) continue;
      e.obstacles.push_back({std::string(kind.label) + std::to_string(k + 1), kind.label, c,
                             kind.radius, kind.height});
      placed = true;
    }
    if (!placed) throw std::runtime_error("convoy episode: no place for obstacle " + std::to_string(k + 1));
  }
  wobble_leader(e, seed, o);
  chain_leader(e, seed, o);
  return e;
}

std::string convoy_scenario_yaml(const ConvoyEpisode& e, const ConvoyScenarioOptions& o) {
  // Reduced dynamics: 10 ms steps (one per frame, the tachometer's 100 Hz); full: 2 ms.
  const double step_s = o.dynamics == ConvoyDynamics::full ? 0.002 : 0.01;
  std::ostringstream y;
  y << "name: convoy_env\n";
  y << "seed: " << (o.seed % 4000000000000000ULL) << "\n";
  y << "time: {step_s: " << num(step_s) << ", heartbeat_s: " << num(kConvoyEnvHeartbeatS)
    << ", end_time_s: "
    << num(o.end_time_s) << "}\n";
  y << "world: {x_min_m: " << num(e.world_min.x()) << ", x_max_m: " << num(e.world_max.x())
    << ", y_min_m: " << num(e.world_min.y()) << ", y_max_m: " << num(e.world_max.y()) << "}\n";
  if (o.terrain == ConvoyTerrain::rigid) {
    y << "terrain: {type: rigid, friction: " << num(o.friction);
    if (o.ground_colour) {
      y << ", colour: [" << num((*o.ground_colour)[0]) << ", " << num((*o.ground_colour)[1])
        << ", " << num((*o.ground_colour)[2]) << "]";
    }
    y << "}\n";
  } else {
    y << "terrain:\n  type: scm\n  preset: "
      << (o.terrain == ConvoyTerrain::scm_soft ? "soft" : "hard") << "\n  spacing_m: "
      << num(o.scm_spacing_m) << "\n  area: {x_min_m: " << num(e.world_min.x() + 5.0)
      << ", x_max_m: " << num(e.world_max.x() - 5.0) << ", y_min_m: " << num(e.world_min.y() + 5.0)
      << ", y_max_m: " << num(e.world_max.y() - 5.0) << "}\n";
  }
  y << "obstacles:\n";
  for (const auto& ob : e.obstacles) {
    y << "  - {id: " << ob.id << ", label: " << ob.label << ", shape: cylinder, position: ["
      << num(ob.centre.x()) << ", " << num(ob.centre.y()) << "], radius_m: " << num(ob.radius_m)
      << ", height_m: " << num(ob.height_m) << "}\n";
  }
  const double rad2deg = 180.0 / std::numbers::pi;
  // A vehicle on reduced dynamics with the convoy rig and V2V; its controller follows.
  const auto lead_vehicle = [&](const char* id, const Vec2& start, double yaw_rad) {
    y << "  - id: " << id << "\n    model: hmmwv\n    dynamics: reduced\n";
    y << "    start: {x: " << num(start.x()) << ", y: " << num(start.y())
      << ", yaw_deg: " << num(yaw_rad * rad2deg) << "}\n";
    y << "    sensors: convoy\n    v2v: {rate_hz: 10, latency_s: 0.0, drop_probability: 0.0}\n";
  };
  const auto path_follower = [&](const std::vector<Vec2>& path) {
    y << "    controller:\n      type: path_follower\n      path: {waypoints: [";
    for (std::size_t i = 0; i < path.size(); ++i) {
      y << (i ? ", [" : "[") << num(path[i].x()) << ", " << num(path[i].y()) << "]";
    }
    y << "]}\n      speed: {profile: ramp, target_mps: " << num(o.target_speed_mps)
      << ", accel_mps2: " << num(o.accel_mps2) << "}\n";
  };
  y << "vehicles:\n";
  if (e.chained) {
    lead_vehicle(kConvoyHeadId, e.head_start, e.head_yaw_rad);
    path_follower(e.head_path);
    lead_vehicle(kConvoyLeaderId, e.leader_start, e.leader_yaw_rad);
    y << "    controller:\n      type: follower\n      follow: " << kConvoyHeadId
      << "\n      gap: {time_s: 1.0, standstill_bumper_m: 5}\n";
  } else {
    lead_vehicle(kConvoyLeaderId, e.leader_start, e.leader_yaw_rad);
    path_follower(e.leader_path);
  }
  y << "  - id: " << kConvoyFollowerId << "\n    model: hmmwv\n    dynamics: "
    << (o.dynamics == ConvoyDynamics::full ? "full" : "reduced") << "\n";
  y << "    start: {x: " << num(e.follower_start.x()) << ", y: " << num(e.follower_start.y())
    << ", yaw_deg: " << num(e.follower_yaw_rad * rad2deg) << "}\n";
  y << "    sensors: " << (o.camera ? "convoy_camera" : "convoy") << "\n";
  y << "    controller: {type: external}\n";
  y << "recorder: {enabled: false}\n";
  return y.str();
}

}  // namespace syndds::learn
