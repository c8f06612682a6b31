#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "control/path_follower.hpp"
#include "scenario/scenario.hpp"
#include "vehicle/bicycle_model.hpp"

using namespace syndds;
using namespace syndds::control;

TEST(Path, PassesThroughWaypointsWithArcLength) {
  Path p({{0, 0}, {10, 0}, {20, 0}}, false);
  EXPECT_NEAR(p.length(), 20.0, 1e-9);
  const auto mid = p.at(10.0);
  EXPECT_NEAR(mid.position.x(), 10.0, 1e-9);
  EXPECT_NEAR(mid.position.y(), 0.0, 1e-9);
  const auto c = p.closest({7.0, 2.0});
  EXPECT_NEAR(c.s, 7.0, 1e-9);
  EXPECT_NEAR(c.lateral_error, 2.0, 1e-9);  // left of the path is positive
}

TEST(Path, ClosedPathWrapsAndIsSmooth) {
  Path p({{0, 0}, {40, 0}, {40, 40}, {0, 40}}, true);
  EXPECT_GT(p.length(), 120.0);
  const auto a = p.at(p.length() + 1.0);
  const auto b = p.at(1.0);
  EXPECT_NEAR((a.position - b.position).norm(), 0.0, 1e-9);
  // Consecutive tangents never turn by more than a few degrees (no kinks).
  for (double s = 0; s < p.length(); s += 0.2) {
    const double turn = std::acos(std::clamp(p.at(s).tangent.dot(p.at(s + 0.2).tangent), -1.0, 1.0));
    EXPECT_LT(turn, deg_to_rad(3.0)) << "at s = " << s;
  }
}

// The windowed search visits only the stretch near near_s; it must pick exactly the point a
// scan of every segment with the window test picks (same segment, same tie-break), on open
// and closed paths, for near_s anywhere (also beyond the length, as a follower's look-ahead
// on a closed loop is) and windows down to an empty one.
TEST(Path, WindowedClosestEqualsAScanOfEverySegment) {
  const std::vector<Path> paths = {
      Path({{0, 0}, {200, 0}, {200, 200}}, true),
      Path({{0, 0}, {30, 5}, {10, 20}, {40, 40}, {0, 45}}, false),
      Path({{0, 0}, {40, 0}, {40, 40}, {0, 40}}, true, 0.5)};
  std::uint64_t seed = 7;
  auto uniform = [&seed](double lo, double hi) {  // splitmix64: the same draws everywhere
    seed += 0x9E3779B97F4A7C15ull;
    std::uint64_t z = seed;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return lo + (hi - lo) * static_cast<double>(z >> 11) / 9007199254740992.0;
  };
  for (const auto& path : paths) {
    const auto& pts = path.samples();
    std::vector<double> s(pts.size(), 0.0);
    for (std::size_t i = 1; i < pts.size(); ++i) s[i] = s[i - 1] + (pts[i] - pts[i - 1]).norm();
    const double length = s.back();
    for (int trial = 0; trial < 2000; ++trial) {
      const Vec2 p(uniform(-20, 220), uniform(-20, 220));
      const double near_s = trial % 50 == 0 ? s[static_cast<std::size_t>(trial) % s.size()]
                                            : uniform(0.0, 1.6 * length);
      const double window = trial % 7 == 0 ? uniform(0.0, 0.3) : uniform(1.0, 60.0);
      // The reference: every segment, the window test, the first strictly closest.
      double best_d2 = std::numeric_limits<double>::infinity();
      std::size_t best_i = 0;
      double best_u = 0.0;
      for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
        double ds = std::abs(s[i] - near_s);
        if (path.closed()) ds = std::min(ds, length - ds);
        if (ds > window && std::abs(s[i + 1] - near_s) > window) continue;
        const Vec2 d = pts[i + 1] - pts[i];
        const double len2 = d.squaredNorm();
        const double u = len2 > 0.0 ? std::clamp((p - pts[i]).dot(d) / len2, 0.0, 1.0) : 0.0;
        const double d2 = (Vec2(pts[i] + u * d) - p).squaredNorm();
        if (d2 < best_d2) {
          best_d2 = d2;
          best_i = i;
          best_u = u;
        }
      }
      const PathPoint got = path.closest(p, near_s, window);
      if (!std::isfinite(best_d2)) {  // nothing in the window: the whole path is searched
        const PathPoint all = path.closest(p);
        EXPECT_EQ(got.s, all.s);
        continue;
      }
      const double want_s = s[best_i] + best_u * (s[best_i + 1] - s[best_i]);
      ASSERT_EQ(got.s, want_s) << "near_s " << near_s << " window " << window << " trial " << trial;
    }
  }
}

TEST(Path, RejectsDegenerateWaypoints) {
  EXPECT_THROW(Path({{1, 1}, {1, 1}}, false), std::invalid_argument);
}

TEST(SpeedProfile, RampRisesToItsCap) {
  SpeedProfile s{SpeedProfile::Kind::ramp, 8.0, 0.47, 0.0};
  EXPECT_DOUBLE_EQ(s.at(0.0), 0.0);
  EXPECT_NEAR(s.at(10.0), 4.7, 1e-12);
  EXPECT_DOUBLE_EQ(s.at(100.0), 8.0);
}

// Closed loop with the reduced model: the follower keeps the vehicle near the path and at the
// target speed.
TEST(PathFollower, TracksACurvedPathAtTheTargetSpeed) {
  const auto params = vehicle::load_vehicle_params(std::string(SYNDDS_TEST_CONFIG_DIR) +
                                                   "/vehicles/hmmwv.yaml");
  Path path({{0, 0}, {40, 0}, {70, 15}, {90, 45}, {90, 120}}, false);
  PathFollowerConfig cfg;
  cfg.speed_profile = {SpeedProfile::Kind::constant, 6.0, 0.0, 0.0};
  PathFollower follower(path, cfg);
  Pose start;
  vehicle::BicycleModel model(params, start, std::make_shared<terrain::FlatTerrain>());
  double max_error = 0.0;
  const double dt = 0.01;
  for (int k = 0; k < 4500; ++k) {
    const auto s = model.snapshot();
    const auto cmd = follower.update(s.time_s, s.pose, s.linear_velocity, dt);
    model.set_inputs(cmd);
    for (int i = 0; i < 5; ++i) model.advance(0.002);
    if (s.time_s > 5.0) max_error = std::max(max_error, std::abs(follower.lateral_error_m()));
    if (s.time_s > 8.0 && s.time_s < 15.0) {
      EXPECT_NEAR(model.speed_mps(), 6.0, 0.5);
    }
  }
  EXPECT_LT(max_error, 1.0);
  // An open path ends at rest near its last point.
  const auto end = model.snapshot();
  EXPECT_LT(model.speed_mps(), 0.1);
  EXPECT_LT((Vec2(end.pose.position.x(), end.pose.position.y()) - Vec2(90, 120)).norm(), 3.0);
}
