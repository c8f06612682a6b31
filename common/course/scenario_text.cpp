#include <cmath>
#include <sstream>

#include "control/path.hpp"
#include "core/text.hpp"
#include "course/course.hpp"

namespace syndds::course {

namespace {

constexpr double kSpacingM = 12.0;     // between vehicles at the start, as the shipped convoys
constexpr double kRampMps2 = 0.47;     // the leader's acceleration (paper)
constexpr double kScmMinM = -32.0;     // SCM patch and world box: the course and the column
constexpr double kScmMaxM = 105.0;     // of four vehicles behind the start (7.5 M vertices)
// The speed the end time is reckoned with. The paper protocol's uncapped ramp only ever asks
// for more, so the same end time bounds its runs too.
constexpr double kReferenceCapMps = 5.0;

std::string num(double v) { return trimmed_decimal(v, 3); }

std::string points(const std::vector<Vec2>& pts) {
  std::string s = "[";
  for (std::size_t i = 0; i < pts.size(); ++i) {
    s += (i ? ", [" : "[") + num(pts[i].x()) + ", " + num(pts[i].y()) + "]";
  }
  return s + "]";
}

// The polyline cut at arc length `length` (leaders behind the first stop short of the goal).
std::vector<Vec2> truncate(const std::vector<Vec2>& pts, double length) {
  std::vector<Vec2> out{pts.front()};
  double acc = 0.0;
  for (std::size_t i = 1; i < pts.size(); ++i) {
    const double d = (pts[i] - pts[i - 1]).norm();
    if (acc + d >= length) {
      out.push_back(pts[i - 1] + (length - acc) / d * (pts[i] - pts[i - 1]));
      return out;
    }
    acc += d;
    out.push_back(pts[i]);
  }
  return out;
}

int leader_count(const std::string& convoy) {
  if (convoy == "1L3F") return 1;
  if (convoy == "2L2F") return 2;
  if (convoy == "3L1F") return 3;
  throw std::invalid_argument("convoy '" + convoy + "': expected 1L3F, 2L2F or 3L1F");
}

// Vehicle k of the column: leaders l1.., then followers f1.. (built with append: GCC 12 warns
// -Wrestrict, wrongly, on "l" + std::to_string(...)).
std::string vehicle_id(int k, int leaders) {
  std::string id(1, k < leaders ? 'l' : 'f');
  return id.append(std::to_string(k < leaders ? k + 1 : k - leaders + 1));
}

}  // namespace

Terrain parse_terrain(const std::string& name) {
  if (name == "rigid") return Terrain::rigid;
  if (name == "scm_hard") return Terrain::scm_hard;
  if (name == "scm_soft") return Terrain::scm_soft;
  throw std::invalid_argument("terrain '" + name + "': expected rigid, scm_hard or scm_soft");
}

std::string terrain_name(Terrain t) {
  switch (t) {
    case Terrain::rigid: return "rigid";
    case Terrain::scm_hard: return "scm_hard";
    case Terrain::scm_soft: return "scm_soft";
  }
  return "?";
}

Protocol parse_protocol(const std::string& name) {
  if (name == "current") return Protocol::current;
  if (name == "paper") return Protocol::paper;
  throw std::invalid_argument("protocol '" + name + "': expected current or paper");
}

std::string protocol_name(Protocol p) { return p == Protocol::paper ? "paper" : "current"; }

Course make_course(std::uint64_t seed, int max_draws) {
  std::string last_error;
  for (int draw = 0; draw < max_draws; ++draw) {
    try {
      Course c;
      c.field = generate_field(seed, draw);
      // The planner's streams depend on the draw too, so a redraw is a fresh problem.
      c.path = plan_path(c.field, seed * 1000003ULL + static_cast<std::uint64_t>(draw));
      c.draw = draw;
      c.placed = c.field.obstacles;
      return c;
    } catch (const CourseError& e) {
      last_error = e.what();
    }
  }
  throw CourseError("course seed " + std::to_string(seed) + ": no field with a path in " +
                    std::to_string(max_draws) + " draws (last: " + last_error + ")");
}

std::vector<Circle> shrink_to_clearance(const std::vector<Circle>& circles,
                                        const std::vector<Vec2>& waypoints) {
  const control::Path spline(waypoints, false);
  std::vector<Circle> out;
  for (const Circle& o : circles) {
    const std::vector<Circle> centre{{o.centre, 0.0}};
    const double d = std::min(polyline_clearance(waypoints, centre),
                              polyline_clearance(spline.samples(), centre));
    const double r = std::min(o.radius, d - kPaperClearanceM);
    out.push_back({o.centre, r < kPaperMinRadiusM ? 0.0 : r});
  }
  return out;
}

Course make_paper_course(std::uint64_t seed) {
  Course c;
  c.protocol = Protocol::paper;
  c.field = generate_field(seed, 0);
  PlannerParams params;
  params.clearance_m = 0.0;  // the paper's path only has to avoid the obstacles
  std::string last_error;
  for (int tenths = 10; tenths >= 1; --tenths) {
    // Where the drawn circles close every way, plan among smaller ones: the paper scales every
    // obstacle to leave room around its path, so the circles the path crosses are shrunk below.
    Field planning = c.field;
    for (Circle& o : planning.obstacles) o.radius *= tenths / 10.0;
    try {
      c.path = plan_path(planning, seed * 1000003ULL, params);
      c.planning_scale = tenths / 10.0;
      break;
    } catch (const CourseError& e) {
      last_error = e.what();
    }
  }
  if (c.path.waypoints.empty()) {
    throw CourseError("course seed " + std::to_string(seed) +
                      ": no path even among the circles shrunk to a tenth (last: " + last_error +
                      ")");
  }
  c.placed = shrink_to_clearance(c.field.obstacles, c.path.waypoints);
  return c;
}

std::pair<int, int> count_scaled(const Course& course) {
  std::pair<int, int> n{0, 0};
  for (std::size_t i = 0; i < course.placed.size() && i < course.field.obstacles.size(); ++i) {
    n.second += course.placed[i].radius == 0.0;
    n.first += course.placed[i].radius > 0.0 &&
               course.placed[i].radius < course.field.obstacles[i].radius;
  }
  return n;
}

Course make_course(std::uint64_t seed, Protocol protocol) {
  return protocol == Protocol::paper ? make_paper_course(seed) : make_course(seed);
}

std::string scenario_yaml(const Course& course, const CourseOptions& o) {
  const int leaders = leader_count(o.convoy);
  if (course.placed.size() != course.field.obstacles.size()) {
    throw std::invalid_argument(
        "course: " + std::to_string(course.placed.size()) + " placed obstacles for a field of " +
        std::to_string(course.field.obstacles.size()) + " (make the course with make_course)");
  }
  const std::string terrain = terrain_name(o.terrain);
  const Vec2 dir = (course.field.goal - course.field.start).normalized();
  const double yaw_deg = std::atan2(dir.y(), dir.x()) * 180.0 / M_PI;
  const double length = course.path.length_m;
  const bool paper = course.protocol == Protocol::paper;
  // The paper's ramp is not capped: its cap is the speed the ramp reaches at the path's end
  // (rounded up to 0.1 m/s), which the leader never needs to reach.
  const double cap_mps =
      paper ? std::ceil(10.0 * std::sqrt(2.0 * kRampMps2 * length)) / 10.0 : o.target_speed_mps;
  // Leader time: ramp to the cap, then the cap; the column behind adds its gaps; soft soil
  // slows the vehicles (the factor is generous: a run that ends early is a failed run).
  const double time_cap_mps = paper ? kReferenceCapMps : o.target_speed_mps;
  const double ramp_s = time_cap_mps / kRampMps2;
  const double ramp_m = 0.5 * kRampMps2 * ramp_s * ramp_s;
  const double drive_s = ramp_s + std::max(0.0, length - ramp_m) / time_cap_mps;
  const double slow = o.terrain == Terrain::scm_soft   ? 1.6
                      : o.terrain == Terrain::scm_hard ? 1.3
                                                       : 1.15;
  const double column_s = 4.0 * (kSpacingM / time_cap_mps + 1.0);
  const int end_time_s = static_cast<int>(std::ceil(slow * drive_s + column_s + 10.0));

  std::ostringstream y;
  y << "# Random obstacle course of the paper's statistical study (docs/ensemble.md): seed "
    << o.seed << ", field draw " << course.draw << (paper ? ", the paper's protocol" : "")
    << ".\n"
    << "# Field x east 0..100 m, y north 0..100 m; the convoy " << o.convoy
    << " drives from the south-west corner to the north-east corner.\n";
  if (paper) {
    const auto [shrunk, left_out] = count_scaled(course);
    y << "# The leader's path was planned by particle swarm optimisation avoiding the obstacles"
      << (course.planning_scale < 1.0 ? " shrunk to " + num(course.planning_scale) +
                                            " of their radius (none wider opens a way)"
                                      : std::string())
      << ";\n# then every obstacle was shrunk to leave 2 m to it (" << shrunk << " shrunk, "
      << left_out << " left out; length " << num(length) << " m).\n";
  } else {
    y << "# The leader's path was planned by particle swarm optimisation keeping "
         "2 m from every obstacle\n"
      << "# (length " << num(length) << " m, clearance " << num(course.path.clearance_m) << " m).";
  }
  y << (paper ? "#" : "") << " Generated by syndds_course: regenerate rather than edit.\n";
  y << "name: convoy_course_" << (paper ? "paper_" : "") << o.seed << "_" << terrain << "\n";
  y << "seed: " << o.seed << "\n";
  y << "time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: " << end_time_s << "}\n";
  y << "coordinator: {join_timeout_s: 30, frame_timeout_s: 20}\n";
  y << "world: {x_min_m: " << num(kScmMinM) << ", x_max_m: " << num(kScmMaxM)
    << ", y_min_m: " << num(kScmMinM) << ", y_max_m: " << num(kScmMaxM) << "}\n";
  if (o.terrain == Terrain::rigid) {
    y << "terrain: {type: rigid, friction: 0.8}\n";
  } else {
    y << "terrain:\n  type: scm\n  preset: " << (o.terrain == Terrain::scm_soft ? "soft" : "hard")
      << "\n  spacing_m: 0.05\n  area: {x_min_m: " << num(kScmMinM)
      << ", x_max_m: " << num(kScmMaxM) << ", y_min_m: " << num(kScmMinM)
      << ", y_max_m: " << num(kScmMaxM) << "}\n";
  }
  y << "obstacles:\n";
  const int fixed = course.field.params.fixed_count;
  for (std::size_t i = 0; i < course.placed.size(); ++i) {
    const Circle& c = course.placed[i];
    if (c.radius == 0.0) continue;
    // Cylinders whose footprint is the obstacle circle: fixed ones are rocks, random ones
    // alternate between trees (a stand of trees as one trunk-shaped solid) and bushes.
    const bool is_fixed = static_cast<int>(i) < fixed;
    const char* label = is_fixed ? "rock" : (i % 2 == 0 ? "tree" : "bush");
    const double height = is_fixed ? 3.0 : (i % 2 == 0 ? 6.0 : 1.5);
    // A shrunk radius is written rounded down to the millimetre, less 2 mm: the text's rounding
    // of the positions and of the path's points (0.5 mm each) then still leaves the 2 m.
    const bool shrunk = c.radius < course.field.obstacles[i].radius;
    const double radius = shrunk ? std::floor(c.radius * 1000.0) / 1000.0 - 0.002 : c.radius;
    y << "  - {id: " << label << i + 1 << ", label: " << label << ", shape: cylinder, position: ["
      << num(c.centre.x()) << ", " << num(c.centre.y()) << "], radius_m: " << num(radius)
      << ", height_m: " << num(height) << "}\n";
  }
  y << "vehicles:\n";
  for (int k = 0; k < 4; ++k) {
    const std::string id = vehicle_id(k, leaders);
    const Vec2 start = course.field.start - kSpacingM * k * dir;
    y << "  - id: " << id << "\n    model: hmmwv\n    dynamics: full\n";
    y << "    start: {x: " << num(start.x()) << ", y: " << num(start.y())
      << ", yaw_deg: " << num(yaw_deg) << "}\n";
    const std::string rig = k < leaders ? "convoy" : o.follower_rig;
    if (k == 3 && o.chase_video) {
      y << "    sensors: {rig: " << rig << "_chase, video: true}\n";
    } else {
      y << "    sensors: " << rig << "\n";
    }
    y << "    v2v: {rate_hz: 10, latency_s: 0.0, drop_probability: 0.0}\n    controller:\n";
    if (k < leaders) {
      // Each leader drives the planned path from its own start, stopping kSpacingM behind the
      // one ahead so that no two vehicles are sent to the same place.
      std::vector<Vec2> path = truncate(course.path.waypoints, length - kSpacingM * k);
      if (k > 0) path.insert(path.begin(), start);
      y << "      type: path_follower\n      path: {waypoints: " << points(path) << "}\n";
      y << "      speed: {profile: ramp, target_mps: " << num(cap_mps) << "}\n";
    } else {
      const std::string ahead = vehicle_id(k - 1, leaders);
      if (o.follower_policy.empty()) {
        y << "      type: follower\n      follow: " << ahead
          << "\n      gap: {time_s: 1.0, standstill_bumper_m: 5}\n";
      } else {
        y << "      type: policy\n      follow: " << ahead << "\n      model: " << o.follower_policy
          << "\n";
      }
      if (o.follower_trail_head) y << "      trail: head\n";
    }
  }
  return y.str();
}

}  // namespace syndds::course
