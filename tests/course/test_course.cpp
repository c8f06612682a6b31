#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "control/path.hpp"
#include "core/yaml.hpp"
#include "course/course.hpp"
#include "scenario/scenario.hpp"

using namespace syndds;
using namespace syndds::course;

namespace {

const double kSqrt2 = std::numbers::sqrt2;

// Exact: every obstacle of 1000 fields obeys the rules the generator promises.
TEST(CourseField, ThousandSeedsObeyTheRules) {
  for (std::uint64_t seed = 0; seed < 1000; ++seed) {
    const Field f = generate_field(seed);
    const auto violations = field_violations(f);
    ASSERT_TRUE(violations.empty()) << "seed " << seed << ": " << violations.front();
  }
}

// field_violations itself detects each broken rule (else the test above proves nothing).
TEST(CourseField, ViolationsAreDetected) {
  const Field good = generate_field(7);
  ASSERT_TRUE(field_violations(good).empty());
  auto broken = [&](auto change) {
    Field f = good;
    change(f);
    return field_violations(f).size();
  };
  EXPECT_GT(broken([](Field& f) { f.obstacles[5].radius = 7.01; }), 0u);
  EXPECT_GT(broken([](Field& f) { f.obstacles[5].radius = 4.99; }), 0u);
  EXPECT_GT(broken([](Field& f) { f.obstacles[5].centre = Vec2(100.5, 50); }), 0u);
  EXPECT_GT(broken([](Field& f) { f.obstacles[5].centre = Vec2(12, 3); }), 0u);   // start
  EXPECT_GT(broken([](Field& f) { f.obstacles[5].centre = Vec2(90, 97); }), 0u);  // goal
  EXPECT_GT(broken([](Field& f) { f.obstacles[1].centre = Vec2(41, 40); }), 0u);  // fixed
  EXPECT_GT(broken([](Field& f) { f.obstacles.pop_back(); }), 0u);
  // Overlap of more than half the smaller radius: two r = 6 circles 8.9 m apart.
  EXPECT_GT(broken([](Field& f) {
              f.obstacles[6] = {f.obstacles[5].centre + Vec2(8.9, 0), f.obstacles[5].radius};
            }),
            0u);
}

TEST(CourseField, FixedObstaclesOnTheDiagonalAndDeterministic) {
  const Field a = generate_field(42);
  const Field b = generate_field(42);
  ASSERT_EQ(a.obstacles.size(), 34u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(a.obstacles[i].centre, Vec2(20.0 * (i + 1), 20.0 * (i + 1)));
    EXPECT_EQ(a.obstacles[i].radius, 8.0);
  }
  for (std::size_t i = 0; i < a.obstacles.size(); ++i) {
    EXPECT_EQ(a.obstacles[i].centre, b.obstacles[i].centre);
    EXPECT_EQ(a.obstacles[i].radius, b.obstacles[i].radius);
  }
  const Field c = generate_field(42, 1);
  EXPECT_NE(a.obstacles[10].centre, c.obstacles[10].centre);  // another draw, another field
  EXPECT_NE(a.obstacles[10].centre, generate_field(43).obstacles[10].centre);
}

TEST(CourseField, ImpossibleFieldIsAClearError) {
  FieldParams p;
  p.random_count = 400;  // cannot fit in 100 x 100 m
  p.attempts_per_obstacle = 200;
  try {
    generate_field(1, 0, p);
    FAIL() << "expected CourseError";
  } catch (const CourseError& e) {
    EXPECT_NE(std::string(e.what()).find("not placed"), std::string::npos) << e.what();
  }
}

// ---- the reference shortest path on cases with known answers ----

TEST(CourseReference, EmptyFieldIsTheDiagonal) {
  std::vector<Vec2> pts;
  const double l = reference_shortest_path({0, 0}, {100, 100}, {}, 100.0, &pts);
  EXPECT_NEAR(l, 100.0 * kSqrt2, 1e-9);
  EXPECT_NEAR(polyline_length(pts), l, 1e-9);
}

// One circle of radius R centred on the diagonal: two tangents of sqrt(D^2 - R^2) and the arc
// between the tangent points, R (pi - 2 acos(R / D)), with D the centre's distance from start.
TEST(CourseReference, OneCircleOnTheDiagonalIsTangentArcTangent) {
  for (double r : {1.0, 10.0, 25.0}) {
    const double d = 50.0 * kSqrt2;
    const double expected =
        2.0 * std::sqrt(d * d - r * r) + r * (std::numbers::pi - 2.0 * std::acos(r / d));
    std::vector<Vec2> pts;
    const double l = reference_shortest_path({0, 0}, {100, 100}, {{Vec2(50, 50), r}}, 100.0, &pts);
    EXPECT_NEAR(l, expected, 1e-9) << "r " << r;
    // The sampled path (arc chords of at most 0.5 m) is slightly shorter, and enters the
    // circle by at most a chord's sagitta, 0.5^2 / (8 r).
    EXPECT_NEAR(polyline_length(pts), expected, 2e-3 * r);
    EXPECT_GE(polyline_clearance(pts, {{Vec2(50, 50), r}}), -0.25 / (8.0 * r) - 1e-9);
  }
}

// A circle on the diagonal whose north-west way round is blocked by a second, overlapping
// circle: the path goes south-east, as long as around the first circle alone.
TEST(CourseReference, OverlappingCircleForcesTheOtherWay) {
  const Circle mid{Vec2(50, 50), 10.0};
  const Circle wall{Vec2(30, 75), 25.0};  // centres 32 m apart, radii 35 m: they overlap
  std::vector<Vec2> pts;
  const double l = reference_shortest_path({0, 0}, {100, 100}, {mid, wall}, 100.0, &pts);
  const double d = 50.0 * kSqrt2;
  const double one =
      2.0 * std::sqrt(d * d - 100.0) + 10.0 * (std::numbers::pi - 2.0 * std::acos(10.0 / d));
  EXPECT_NEAR(l, one, 1e-9);  // the south-east way around is free and as short
  for (const Vec2& p : pts) EXPECT_LE(p.y() - p.x(), 1e-9);  // south-east of the diagonal
}

TEST(CourseReference, DomainEdgeBlocksAndDisconnects) {
  // A circle across the whole width: no path.
  EXPECT_TRUE(std::isinf(reference_shortest_path({0, 0}, {100, 100}, {{Vec2(50, 50), 80.0}},
                                                 100.0)));
  // Along the west edge past a circle reaching across it: the way round its west side would
  // leave the square, so the path goes round its east side and stays in the square.
  std::vector<Vec2> pts;
  const double l = reference_shortest_path({0, 0}, {0, 100}, {{Vec2(-5, 50), 15.0}}, 100.0, &pts);
  ASSERT_TRUE(std::isfinite(l));
  EXPECT_TRUE(polyline_in_square(pts, 100.0, 1e-6));
  EXPECT_GT(l, 100.0);
}

// ---- the PSO path ----

TEST(CoursePlanner, FiftySeedsClearInTheSquareAndWithinFivePercentOfShortest) {
  const PlannerParams params;
  double worst = 0.0;
  int planned = 0;
  for (std::uint64_t seed = 0; seed < 50; ++seed) {
    const Course c = make_course(seed);
    ++planned;
    const PlannedPath& p = c.path;
    EXPECT_GE(polyline_clearance(p.waypoints, c.field.obstacles), params.clearance_m)
        << "seed " << seed;
    EXPECT_GE(p.clearance_m, params.clearance_m) << "seed " << seed;
    EXPECT_TRUE(polyline_in_square(p.waypoints, 100.0)) << "seed " << seed;
    EXPECT_EQ(p.waypoints.front(), c.field.start);
    EXPECT_EQ(p.waypoints.back(), c.field.goal);
    std::vector<Circle> inflated;
    for (const Circle& o : c.field.obstacles) inflated.push_back({o.centre, o.radius + 2.0});
    const double ref = reference_shortest_path(c.field.start, c.field.goal, inflated, 100.0);
    ASSERT_TRUE(std::isfinite(ref)) << "seed " << seed;
    // The reference is the shortest: nothing feasible is shorter.
    EXPECT_GE(p.length_m, ref - 1e-6) << "seed " << seed;
    EXPECT_LE(p.length_m, 1.05 * ref) << "seed " << seed << " draw " << c.draw;
    worst = std::max(worst, p.length_m / ref - 1.0);
  }
  RecordProperty("worst_excess_percent", std::to_string(100.0 * worst));
  std::printf("worst PSO excess over the shortest path: %.2f %% (%d courses)\n", 100 * worst,
              planned);
}

TEST(CoursePlanner, DeterministicPerSeed) {
  const Course a = make_course(3);
  const Course b = make_course(3);
  ASSERT_EQ(a.path.waypoints.size(), b.path.waypoints.size());
  for (std::size_t i = 0; i < a.path.waypoints.size(); ++i) {
    EXPECT_EQ(a.path.waypoints[i], b.path.waypoints[i]);
  }
}

TEST(CoursePlanner, BlockedFieldIsAClearError) {
  Field f = generate_field(1);
  f.obstacles.push_back({Vec2(50, 50), 60.0});  // covers the middle of the field
  try {
    plan_path(f, 1, PlannerParams{.particles = 10, .iterations = 10, .swarms = 1,
                                  .attempts = 2});
    FAIL() << "expected CourseError";
  } catch (const CourseError& e) {
    EXPECT_NE(std::string(e.what()).find("no way from start to goal keeping 2"), std::string::npos)
        << e.what();
  }
}

// ---- the scenario ----

scenario::Scenario load_text(const std::string& text) {
  const YamlNode root = YamlNode::load_string(text, "course.yaml");
  return scenario::parse_scenario_config(root, text, {}, SYNDDS_TEST_CONFIG_DIR);
}

TEST(CourseScenario, LoadsWithTheConvoyAndTheObstacles) {
  const Course c = make_course(5);
  for (Terrain t : {Terrain::rigid, Terrain::scm_hard, Terrain::scm_soft}) {
    for (const char* mix : {"1L3F", "2L2F", "3L1F"}) {
      CourseOptions o;
      o.seed = 5;
      o.terrain = t;
      o.convoy = mix;
      const std::string text = scenario_yaml(c, o);
      EXPECT_EQ(text, scenario_yaml(c, o));
      const scenario::Scenario s = load_text(text);
      EXPECT_EQ(s.name, "convoy_course_5_" + terrain_name(t));
      EXPECT_EQ(s.seed, 5u);
      ASSERT_EQ(s.vehicles.size(), 4u);
      ASSERT_EQ(s.obstacles.size(), 34u);
      EXPECT_EQ(s.vehicles[0].id, "l1");
      const int leaders = mix[0] - '0';
      EXPECT_EQ(s.vehicles[leaders - 1].id, "l" + std::to_string(leaders));
      EXPECT_EQ(s.vehicles[3].id, "f" + std::to_string(4 - leaders));
      // The first leader drives the planned path; every vehicle starts in the world box and
      // outside every obstacle (a follower column on the start diagonal, behind the field).
      EXPECT_EQ(s.vehicles[0].start.position.x(), 0.0);
      EXPECT_LT(s.vehicles[3].start.position.x(), -25.0);
    }
  }
}

// The 2L2F scenario of course 5 with `set` applied to its options.
template <typename Set>
scenario::Scenario course5_2l2f(Set&& set) {
  CourseOptions o;
  o.seed = 5;
  o.convoy = "2L2F";
  set(o);
  return load_text(scenario_yaml(make_course(5), o));
}

// With a follower policy every follower is that learned policy, following the vehicle ahead.
TEST(CourseScenario, FollowersCanBeALearnedPolicy) {
  const scenario::Scenario s =
      course5_2l2f([](CourseOptions& o) { o.follower_policy = "policies/convoy_follow_lowdim.pt"; });
  ASSERT_EQ(s.vehicles.size(), 4u);
  EXPECT_EQ(s.vehicles[1].controller.type, "path_follower");
  for (const int k : {2, 3}) {
    EXPECT_EQ(s.vehicles[k].controller.type, "policy");
    EXPECT_EQ(s.vehicles[k].controller.convoy.leader, s.vehicles[k - 1].id);
    EXPECT_TRUE(s.vehicles[k].controller.policy_file.ends_with("policies/convoy_follow_lowdim.pt"));
  }
}

// follower_trail_head: every follower steers along the trail of its convoy's head (the last
// leader, whose path the followers' chain ends at) and keeps following the vehicle ahead.
TEST(CourseScenario, FollowersCanSteerAlongTheHeadsTrail) {
  const scenario::Scenario ahead = course5_2l2f([](CourseOptions&) {});
  const scenario::Scenario head = course5_2l2f([](CourseOptions& o) { o.follower_trail_head = true; });
  for (const int k : {2, 3}) {
    EXPECT_EQ(ahead.vehicles[k].controller.convoy.trail_of, "");
    EXPECT_EQ(head.vehicles[k].controller.convoy.trail_of, "l2");
    EXPECT_EQ(head.vehicles[k].controller.convoy.leader, head.vehicles[k - 1].id);
  }
}

// Followers with cameras: follower_rig gives every follower the rig (leaders keep convoy) and
// the last, filming the chase video, <rig>_chase, whose first camera is the front camera a
// camera policy observes.
TEST(CourseScenario, FollowersCanCarryTheCameraRig) {
  const scenario::Scenario s =
      course5_2l2f([](CourseOptions& o) { o.follower_rig = "convoy_camera"; });
  ASSERT_EQ(s.vehicles.size(), 4u);
  EXPECT_EQ(s.vehicles[0].sensors->rig.name, "convoy");
  EXPECT_EQ(s.vehicles[1].sensors->rig.name, "convoy");
  EXPECT_EQ(s.vehicles[2].sensors->rig.name, "convoy_camera");
  EXPECT_EQ(s.vehicles[3].sensors->rig.name, "convoy_camera_chase");
  for (const int k : {2, 3}) {
    ASSERT_FALSE(s.vehicles[k].sensors->rig.cameras.empty());
    EXPECT_EQ(s.vehicles[k].sensors->rig.cameras.front().id, "front_camera");
    EXPECT_EQ(s.vehicles[k].sensors->rig.cameras.front().intrinsics.width, 80);
  }
}

// The chase camera behind the last vehicle is the course's default; a study leaves it out and
// every vehicle carries the plain convoy rig.
TEST(CourseScenario, TheChaseVideoCanBeLeftOut) {
  const Course c = make_course(5);
  CourseOptions o;
  o.seed = 5;
  const std::string with = scenario_yaml(c, o);
  EXPECT_NE(with.find("    sensors: {rig: convoy_chase, video: true}\n"), std::string::npos);
  o.chase_video = false;
  const std::string without = scenario_yaml(c, o);
  EXPECT_EQ(without.find("convoy_chase"), std::string::npos);
  std::size_t plain = 0;
  for (std::size_t at = 0; (at = without.find("    sensors: convoy\n", at)) != std::string::npos;
       ++at) {
    ++plain;
  }
  EXPECT_EQ(plain, 4u);
  EXPECT_EQ(load_text(without).vehicles.size(), 4u);
}

TEST(CourseScenario, BadOptionsNameThemselves) {
  const Course c = make_course(5);
  CourseOptions o;
  o.convoy = "4L0F";
  try {
    scenario_yaml(c, o);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("4L0F"), std::string::npos);
  }
  EXPECT_THROW(parse_terrain("mud"), std::invalid_argument);
  EXPECT_EQ(parse_terrain("scm_soft"), Terrain::scm_soft);
}

// ---- the paper protocol ----

// Distance from a point to the nearer of the polyline and the spline the leader drives.
double path_distance(const std::vector<Vec2>& waypoints, const Vec2& p) {
  const std::vector<Circle> point{{p, 0.0}};
  return std::min(polyline_clearance(waypoints, point),
                  polyline_clearance(control::Path(waypoints, false).samples(), point));
}

// The paper's scaling on a straight path along y = 0: a circle is kept, shrunk to leave 2 m,
// or left out when less than kPaperMinRadiusM would remain.
TEST(CoursePaperProtocol, ObstaclesShrinkToLeaveTwoMetresToThePath) {
  const std::vector<Vec2> path{Vec2(0, 0), Vec2(100, 0)};
  const std::vector<Circle> in{{Vec2(50, 20), 6.0},   // 20 m away: kept
                               {Vec2(30, -5), 4.0},   // 5 m away: 3 m left
                               {Vec2(70, 2.1), 1.0},  // 0.1 m would be left: out
                               {Vec2(90, 8), 6.0}};   // exactly 6 + 2: kept
  const std::vector<Circle> out = shrink_to_clearance(in, path);
  ASSERT_EQ(out.size(), in.size());
  EXPECT_DOUBLE_EQ(out[0].radius, 6.0);
  EXPECT_NEAR(out[1].radius, 3.0, 1e-9);
  EXPECT_EQ(out[2].radius, 0.0);
  EXPECT_NEAR(out[3].radius, 6.0, 1e-9);
  for (std::size_t i = 0; i < in.size(); ++i) EXPECT_EQ(out[i].centre, in[i].centre);
}

// Every seed's first field is used; the path avoids the circles it was planned among; every
// placed obstacle leaves >= 2 m to the path the leader drives, and one is smaller than drawn
// only where that 2 m required it.
TEST(CoursePaperProtocol, EveryFieldIsUsedAndEveryObstacleLeavesTwoMetres) {
  int shrunk_fields = 0;
  for (std::uint64_t seed = 1; seed <= 30; ++seed) {
    const Course c = make_paper_course(seed);
    EXPECT_EQ(c.protocol, Protocol::paper);
    EXPECT_EQ(c.draw, 0);
    const Field drawn = generate_field(seed, 0);
    ASSERT_EQ(c.field.obstacles.size(), drawn.obstacles.size());
    ASSERT_EQ(c.placed.size(), drawn.obstacles.size());
    EXPECT_TRUE(polyline_in_square(c.path.waypoints, 100.0)) << "seed " << seed;
    std::vector<Circle> planning = drawn.obstacles;
    for (Circle& o : planning) o.radius *= c.planning_scale;
    EXPECT_GE(polyline_clearance(c.path.waypoints, planning), 0.0) << "seed " << seed;
    shrunk_fields += c.planning_scale < 1.0;
    for (std::size_t i = 0; i < c.placed.size(); ++i) {
      const Circle& o = drawn.obstacles[i];
      const Circle& p = c.placed[i];
      EXPECT_EQ(p.centre, o.centre);
      EXPECT_LE(p.radius, o.radius);
      const double d = path_distance(c.path.waypoints, o.centre);
      if (p.radius > 0.0) {
        EXPECT_GE(d - p.radius, kPaperClearanceM - 1e-9) << "seed " << seed;
      }
      if (p.radius > 0.0 && p.radius < o.radius) {
        EXPECT_NEAR(d - p.radius, kPaperClearanceM, 1e-9) << "seed " << seed;
      }
    }
  }
  // Seeds 1..30 cover both cases: fields with a way through as drawn, and fields whose
  // circles had to be shrunk to plan (4 of these 30).
  EXPECT_GT(shrunk_fields, 0);
  EXPECT_LT(shrunk_fields, 30);
}

TEST(CoursePaperProtocol, ScenarioHasTheUncappedRampAndThePlacedObstacles) {
  const Course c = make_course(5, Protocol::paper);
  CourseOptions o;
  o.seed = 5;
  o.terrain = Terrain::scm_hard;
  const std::string text = scenario_yaml(c, o);
  EXPECT_EQ(text, scenario_yaml(make_paper_course(5), o));  // deterministic
  const scenario::Scenario s = load_text(text);
  EXPECT_EQ(s.name, "convoy_course_paper_5_scm_hard");
  std::size_t kept = 0;
  for (const Circle& p : c.placed) kept += p.radius > 0.0;
  ASSERT_EQ(s.obstacles.size(), kept);
  // Each written obstacle is its placed circle (a shrunk one 2-3 mm smaller, for the text's
  // rounding), and the written path keeps >= 2 m from each as written.
  const std::vector<Vec2>& written = s.vehicles[0].controller.waypoints;
  for (const auto& ob : s.obstacles) {
    bool found = false;
    for (const Circle& p : c.placed) {
      found |= std::abs(p.centre.x() - ob.pose.position.x()) < 1e-3 &&
               std::abs(p.centre.y() - ob.pose.position.y()) < 1e-3 &&
               ob.size.x() <= p.radius + 1e-3 && ob.size.x() > p.radius - 3.5e-3;
    }
    EXPECT_TRUE(found) << ob.id;
    const Vec2 centre(ob.pose.position.x(), ob.pose.position.y());
    EXPECT_GE(path_distance(written, centre) - ob.size.x(), kPaperClearanceM) << ob.id;
  }
  // The ramp's cap is the speed it would reach at the path's end: never reached before it.
  const auto& speed = s.vehicles[0].controller.follower.speed_profile;
  EXPECT_GE(speed.target_mps, std::sqrt(2.0 * 0.47 * c.path.length_m));
  EXPECT_LT(speed.target_mps, std::sqrt(2.0 * 0.47 * c.path.length_m) + 0.1);
  // The end time is the current protocol's for the same path (the faster ramp only arrives
  // sooner).
  Course capped = c;
  capped.protocol = Protocol::current;
  EXPECT_EQ(s.time.end_time_s, load_text(scenario_yaml(capped, o)).time.end_time_s);
  EXPECT_EQ(parse_protocol("paper"), Protocol::paper);
  EXPECT_THROW(parse_protocol("chrono"), std::invalid_argument);
  Course broken = c;
  broken.placed.pop_back();
  EXPECT_THROW(scenario_yaml(broken, o), std::invalid_argument);
}

}  // namespace
