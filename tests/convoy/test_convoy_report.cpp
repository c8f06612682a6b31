// The convoy report on tracks whose answers are known in closed form.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

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

TEST(ConvoyReport, BumperGapIsBoxToBoxAndCountsTheTimeBelowStandstill) {
  // HMMWV boxes (4.7 m long, centred on the reference point lengthwise). The leader stands at
  // x = 20; the follower rolls from x = 0.005 towards it at 1 m/s for 13 s, ending 6.995 m
  // centre to centre behind it: bumper gap 20 - x - 4.7, smallest 2.295 m at t = 13 s. Below
  // the 5 m standstill gap once x > 10.3: from t = 10.30 s on, 271 frames of 0.01 s.
  const BodyBox hmmwv{Vec3(0.0, 0.0, 0.45), Vec3(2.35, 1.08, 0.55)};
  Track leader, follower;
  for (int k = 0; k <= 1300; ++k) {
    const double t = k * 0.01;
    leader.push_back({t, Vec2(20.0, 0.0), 0.0});
    follower.push_back({t, Vec2(k * 0.01 + 0.005, 0.0), 1.0});
  }
  const auto r = follower_report("f1", "l1", follower, leader, 0, 0, {hmmwv, hmmwv, 5.0}, 0.01);
  EXPECT_NEAR(r.bumper_gap_m.min, 2.295, 1e-9);
  EXPECT_NEAR(r.bumper_gap_m.max, 15.295, 1e-9);
  EXPECT_EQ(r.bumper_gap_m.samples, 1301u);
  EXPECT_NEAR(r.min_bumper_gap_time_s, 13.0, 1e-9);
  EXPECT_EQ(r.standstill_bumper_m, 5.0);
  EXPECT_NEAR(r.time_below_standstill_s, 2.71, 1e-9);
  // The centre distance is still the distance gap.
  EXPECT_NEAR(r.distance_gap_m.min, 6.995, 1e-9);

  // The leader turned 90 degrees (crossing): its side, 1.08 m from its centre, faces the
  // follower's front.
  for (auto& p : leader) p.orientation = quat_from_yaw(std::numbers::pi / 2.0);
  const auto turned =
      follower_report("f1", "l1", follower, leader, 0, 0, {hmmwv, hmmwv, 5.0}, 0.01);
  EXPECT_NEAR(turned.bumper_gap_m.min, 6.995 - 2.35 - 1.08, 1e-9);
}

// Stuck: the follower drives 3 m/s behind its leader on the same line, stops for good at
// t = 12 s while the leader drives on: seen stuck once a whole window (10 s) has brought it
// less than 0.5 m, i.e. 10 s less 0.5 m / (3 m/s) after it stopped. Not stuck: the same
// follower stopping behind a leader that stopped too, or driving on.
TEST(ConvoyReport, AFollowerStoppedForGoodWhileItsLeaderDrivesOnIsStuck) {
  const auto run = [](double follower_stop_s, double leader_stop_s) {
    Track leader, follower;
    for (int k = 0; k <= 4000; ++k) {
      const double t = k * 0.01;
      const double tl = std::min(t, leader_stop_s), tf = std::min(t, follower_stop_s);
      leader.push_back({t, Vec2(20.0 + 3.0 * tl, 0.0), t < leader_stop_s ? 3.0 : 0.0});
      follower.push_back({t, Vec2(3.0 * tf, 0.0), t < follower_stop_s ? 3.0 : 0.0});
    }
    return follower_report("f1", "l1", follower, leader, 0, 0);
  };
  const auto stuck = run(12.0, 1e9);
  EXPECT_TRUE(stuck.stuck);
  EXPECT_NEAR(stuck.stuck_time_s, 12.0 + 10.0 - 0.5 / 3.0, 0.02);
  const auto both_stopped = run(12.0, 12.0);
  EXPECT_FALSE(both_stopped.stuck);
  EXPECT_EQ(both_stopped.stuck_time_s, -1.0);
  // Driving on: for its first 6.7 s the follower is behind the start of its leader's track,
  // where progress is minus the distance still to go, so a follower still coming is not stuck.
  EXPECT_FALSE(run(1e9, 1e9).stuck);
}
