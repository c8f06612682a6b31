// The convoy report on tracks whose answers are known in closed form.
#include <gtest/gtest.h>

#include <cmath>

#include "convoy/convoy_report.hpp"

using namespace syndds;
using namespace syndds::convoy;

namespace {

// A leader driving east at v from x = 0; a follower on a parallel line `offset` to the side,
// `delay` seconds behind (it waits at x = 0 until then).
void tracks(double v, double offset, double delay, Track& leader, Track& follower) {
  for (int k = 0; k <= 3000; ++k) {
    const double t = k * 0.01;
    leader.push_back({t, Vec2(v * t, 0.0), v});
    const double tf = std::max(0.0, t - delay);
    follower.push_back({t, Vec2(v * tf, offset), t < delay ? 0.0 : v});
  }
}

}  // namespace

TEST(ConvoyReport, ParallelDelayedFollowerHasKnownGaps) {
  Track leader, follower;
  tracks(6.0, 0.3, 2.0, leader, follower);
  const auto r = follower_report("f1", "l1", follower, leader, 1, 2);
  EXPECT_EQ(r.obstacles_hit, 1u);
  EXPECT_EQ(r.leader_lost_events, 2u);
  // Cross-track: 0.3 m wherever the follower is beside the leader's track (x > 0).
  EXPECT_NEAR(r.cross_track_m.mean, 0.3, 1e-9);
  EXPECT_NEAR(r.cross_track_m.max, 0.3, 1e-9);
  // Time gap: exactly the delay while it moves.
  EXPECT_NEAR(r.time_gap_s.mean, 2.0, 1e-6);
  EXPECT_NEAR(r.time_gap_s.min, 2.0, 1e-6);
  EXPECT_NEAR(r.time_gap_s.max, 2.0, 1e-6);
  // Distance gap: grows to v * delay while the follower waits, then stays there (hypot with
  // the offset).
  EXPECT_NEAR(r.distance_gap_m.max, std::hypot(12.0, 0.3), 1e-9);
  EXPECT_NEAR(r.distance_gap_m.min, 0.3, 1e-9);
}

TEST(ConvoyReport, PointsBeyondTheTrackEndsAreNotCrossTrack) {
  std::vector<Vec2> track = {Vec2(0, 0), Vec2(10, 0)};
  std::vector<double> arc = {0.0, 10.0};
  double u = 0.0;
  bool inside = true;
  EXPECT_NEAR(distance_to_track(track, arc, Vec2(-5, 1), u, inside), std::hypot(5.0, 1.0), 1e-12);
  EXPECT_FALSE(inside);
  EXPECT_NEAR(distance_to_track(track, arc, Vec2(4, -2), u, inside), 2.0, 1e-12);
  EXPECT_TRUE(inside);
  EXPECT_NEAR(u, 4.0, 1e-12);
}
