// The follower's obstacle memory: a camera's range reading placed in the world from the
// follower's pose, cells kept after the camera has passed them, taken back when a later ray
// sees through them, and forgotten far behind.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "convoy/obstacle_memory.hpp"

using namespace syndds;
using namespace syndds::convoy;

namespace {

// One ray straight ahead (a field of view of 10 degrees), range 20 m.
RangeReading ahead(const std::vector<float>& ranges, double camera_ahead_m = 0.0) {
  return {ranges, 10.0 * std::numbers::pi / 180.0, 20.0, camera_ahead_m};
}

}  // namespace

TEST(ObstacleMemory, AReadingMarksTheCellWhereTheRayStops) {
  ObstacleMemory memory;  // cells of 0.5 m
  const std::vector<float> at_10m = {0.5f};
  // Facing north (yaw pi/2) from (1, 2), camera 2 m ahead: the hit is at (1, 14).
  memory.observe(Vec2(1.0, 2.0), std::numbers::pi / 2.0, ahead(at_10m, 2.0));
  const auto circles = memory.circles();
  ASSERT_EQ(circles.size(), 1u);
  EXPECT_NEAR(circles[0].centre.x(), 1.25, 1e-9);  // the cell [1, 1.5) x [14, 14.5)
  EXPECT_NEAR(circles[0].centre.y(), 14.25, 1e-9);
  EXPECT_NEAR(circles[0].radius_m, 0.5 * std::sqrt(0.5), 1e-12);
  // Nothing in range marks nothing.
  ObstacleMemory empty;
  const std::vector<float> nothing = {1.0f};
  empty.observe(Vec2::Zero(), 0.0, ahead(nothing));
  EXPECT_EQ(empty.size(), 0u);
}

TEST(ObstacleMemory, ACellStaysUntilARaySeesThroughItOrItIsFarBehind) {
  ObstacleMemory memory;
  const std::vector<float> at_10m = {0.5f}, at_18_25m = {0.9125f}, nothing = {1.0f};
  memory.observe(Vec2::Zero(), 0.0, ahead(at_10m));  // (10, 0)
  ASSERT_EQ(memory.size(), 1u);
  // Looking elsewhere (north) leaves it.
  memory.observe(Vec2::Zero(), std::numbers::pi / 2.0, ahead(nothing));
  EXPECT_EQ(memory.size(), 1u);
  // A reading that stops just past it (within the clearing margin) leaves it.
  const std::vector<float> at_10_6m = {0.53f};
  memory.observe(Vec2::Zero(), 0.0, ahead(at_10_6m));
  EXPECT_EQ(memory.size(), 2u);  // and marks (10.6, 0)
  // A ray that reads 18.25 m along the same line sees through both: they go, (18.25, 0) comes.
  memory.observe(Vec2::Zero(), 0.0, ahead(at_18_25m));
  const auto circles = memory.circles();
  ASSERT_EQ(circles.size(), 1u);
  EXPECT_NEAR(circles[0].centre.x(), 18.25, 1e-9);
  // 30 m is remembered, farther is forgotten.
  memory.observe(Vec2(-11.0, 0.0), std::numbers::pi / 2.0, ahead(nothing));
  EXPECT_EQ(memory.size(), 1u);
  memory.observe(Vec2(-13.0, 0.0), std::numbers::pi / 2.0, ahead(nothing));
  EXPECT_EQ(memory.size(), 0u);
}

TEST(ObstacleMemory, ABadReadingIsRefused) {
  ObstacleMemory memory;
  const std::vector<float> one = {0.5f};
  EXPECT_THROW(memory.observe(Vec2::Zero(), 0.0, RangeReading{{}, 1.0, 20.0, 0.0}),
               std::invalid_argument);
  EXPECT_THROW(memory.observe(Vec2::Zero(), 0.0, RangeReading{one, 0.0, 20.0, 0.0}),
               std::invalid_argument);
  EXPECT_THROW(memory.observe(Vec2::Zero(), 0.0, RangeReading{one, 1.0, 0.0, 0.0}),
               std::invalid_argument);
}
