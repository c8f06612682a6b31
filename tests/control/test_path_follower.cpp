#include <gtest/gtest.h>

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
