// The deviation metrics on constructed tracks whose answers are known: identical tracks, a
// lateral offset on a straight and on a circle, a follower at a fixed fraction of the leader's
// speed, and one case for each rule (start clip, end clip, the first 10 m, a standing leader),
// plus the resolution of follow chains. Tracks on straights use 0.25 m steps (exact in binary),
// so that samples every 0.5 m fall exactly on recorded points.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>

#include "metrics/deviation.hpp"

using namespace syndds;
using namespace syndds::metrics;

namespace {

// Points along x from x0 to x1 (0.25 m steps) at height y; speed(x) gives the speed there.
Trajectory straight(double x0, double x1, double y, const std::function<double(double)>& speed) {
  Trajectory t;
  const int n = static_cast<int>(std::lround((x1 - x0) / 0.25));
  for (int i = 0; i <= n; ++i) {
    const double x = x0 + 0.25 * i;
    t.push_back({0.01 * i, Vec2(x, y), speed(x)});
  }
  return t;
}

std::function<double(double)> constant(double v) {
  return [v](double) { return v; };
}

void expect_zero(const Deviation& d) {
  EXPECT_EQ(d.avg, 0.0);
  EXPECT_EQ(d.max, 0.0);
}

}  // namespace

TEST(Deviations, IdenticalTracksGiveZero) {
  const Trajectory t = straight(0, 100, 0, [](double x) { return 2.0 + 0.05 * x; });
  const Deviations d = deviations(t, t);
  expect_zero(d.path_m);
  expect_zero(d.abs_speed_mps);
  expect_zero(d.rel_speed);
  EXPECT_EQ(d.samples, 201u);  // 0, 0.5, ..., 100 m
  EXPECT_EQ(d.abs_speed_mps.samples, 181u);  // 10 m, ..., 100 m
  EXPECT_EQ(d.rel_speed.samples, 181u);
  EXPECT_EQ(d.leader_segment_m, 100.0);
  EXPECT_EQ(d.follower_segment_m, 100.0);
}

// The follower's points lie on the same lines as the leader's: the projection is exact.
TEST(Deviations, LateralOffsetOnAStraightIsThePathDeviation) {
  const Trajectory leader = straight(0, 100, 0, constant(5));
  const Trajectory follower = straight(0, 100, 0.7, constant(5));
  const Deviations d = deviations(follower, leader);
  EXPECT_NEAR(d.path_m.avg, 0.7, 1e-12);
  EXPECT_NEAR(d.path_m.max, 0.7, 1e-12);
  EXPECT_EQ(d.samples, 201u);
  expect_zero(d.abs_speed_mps);
}

// On a circle both tracks are polygons (one point per frame): a chord lies inside its arc by at
// most r (1 - cos(dtheta / 2)), so the deviation is d within the two sagittas.
TEST(Deviations, LateralOffsetOnACircleIsThePathDeviation) {
  const double r = 20.0, offset = 1.0, dtheta = 5.0 * 0.01 / r;  // 5 m/s, 0.01 s frames
  Trajectory leader, follower;
  for (int i = 0; i * dtheta <= 1.5 * std::numbers::pi; ++i) {
    const double a = i * dtheta;
    const Vec2 u(std::cos(a), std::sin(a));
    leader.push_back({0.01 * i, r * u, 5.0});
    follower.push_back({0.01 * i, (r + offset) * u, 5.0 * (r + offset) / r});
  }
  const auto sagitta = [&](double radius) { return radius * (1.0 - std::cos(dtheta / 2.0)); };
  const double tolerance = sagitta(r) + sagitta(r + offset);  // 3.2e-5 m
  const Deviations d = deviations(follower, leader);
  EXPECT_NEAR(d.path_m.avg, offset, tolerance);
  EXPECT_NEAR(d.path_m.max, offset, tolerance);
  // Up to three quarters of the circle: the leader's whole polygon, sampled every 0.5 m.
  const double chords = static_cast<double>(leader.size() - 1);
  EXPECT_EQ(d.leader_end_index, leader.size() - 1);
  EXPECT_NEAR(d.leader_segment_m, chords * 2.0 * r * std::sin(dtheta / 2.0), 1e-9);
  EXPECT_EQ(d.samples, static_cast<std::size_t>(d.leader_segment_m / 0.5) + 1);
  // The outer track is driven at the same angular rate: 5 % faster.
  EXPECT_NEAR(d.rel_speed.avg, 0.05, 1e-12);
  EXPECT_NEAR(d.abs_speed_mps.max, 0.25, 1e-12);
}

TEST(Deviations, AFixedFractionOfTheLeadersSpeed) {
  const auto v = [](double x) { return 2.0 + 0.05 * x; };
  const double fraction = 0.8;
  const Trajectory leader = straight(0, 100, 0, v);
  const Trajectory follower = straight(0, 100, 0, [&](double x) { return fraction * v(x); });
  const Deviations d = deviations(follower, leader);
  expect_zero(d.path_m);
  EXPECT_NEAR(d.rel_speed.avg, 1.0 - fraction, 1e-12);
  EXPECT_NEAR(d.rel_speed.max, 1.0 - fraction, 1e-12);
  // m_as = (1 - fraction) v(s) over s = 10, 10.5, ..., 100: mean of v is v(55).
  EXPECT_NEAR(d.abs_speed_mps.avg, (1.0 - fraction) * v(55.0), 1e-12);
  EXPECT_NEAR(d.abs_speed_mps.max, (1.0 - fraction) * v(100.0), 1e-12);
}

// The follower waited beside the route 10 m ahead of the leader's start (0.2 m to the side,
// standing), drove round and then along the route 0.3 m to the side. Without the start clip
// the sample at 10 m would pair with the waiting point (0.2 m, speed 0).
TEST(Deviations, TheStartClipDropsWhatTheFollowerDidBeforeTheLeadersStart) {
  const Trajectory leader = straight(0, 100, 0, constant(5));
  Trajectory follower;
  for (int i = 0; i < 50; ++i) follower.push_back({0.01 * i, Vec2(10, 0.2), 0.0});
  for (const Vec2& p : {Vec2(10, 20), Vec2(-20, 20), Vec2(-20, 0.3)}) {
    follower.push_back({follower.back().time_s + 5, p, 5.0});
  }
  const std::size_t start = follower.size() + 79;  // x = 0: 79 steps after -19.75
  for (const auto& p : straight(-19.75, 100, 0.3, constant(5))) follower.push_back(p);
  ASSERT_EQ(follower[start].position.x(), 0.0);

  const Deviations d = deviations(follower, leader);
  EXPECT_EQ(d.follower_start_index, start);
  EXPECT_EQ(d.follower_segment_m, 100.0);
  EXPECT_NEAR(d.path_m.avg, 0.3, 1e-12);
  EXPECT_NEAR(d.path_m.max, 0.3, 1e-12);
  expect_zero(d.abs_speed_mps);
}

// The follower stopped at 80 m, the leader drove on to 100 m: without the end clip the last
// 20 m would pair with the follower's end point, up to 20 m away.
TEST(Deviations, TheEndClipStopsTheSegmentWhereTheFollowerEnded) {
  const Trajectory leader = straight(0, 100, 0, constant(5));
  const Trajectory follower = straight(0, 80, 0, constant(5));
  const Deviations d = deviations(follower, leader);
  EXPECT_EQ(d.leader_end_index, 320u);
  EXPECT_EQ(d.leader_segment_m, 80.0);
  EXPECT_EQ(d.samples, 161u);
  expect_zero(d.path_m);
  expect_zero(d.abs_speed_mps);
}

TEST(Deviations, TheFirstTenMetresDoNotCountForSpeed) {
  const Trajectory leader = straight(0, 100, 0, constant(5));
  // Slower only before 10 m: nothing counts.
  const Trajectory early = straight(0, 100, 0, [](double x) { return x < 10 ? 2.0 : 5.0; });
  const Deviations d = deviations(early, leader);
  expect_zero(d.abs_speed_mps);
  expect_zero(d.rel_speed);
  EXPECT_EQ(d.abs_speed_mps.samples, 181u);
  // The same 10 m later counts: 20 of the 181 samples (10, 10.5, ..., 19.5 m) are 3 m/s off.
  const Trajectory later =
      straight(0, 100, 0, [](double x) { return x >= 10 && x < 20 ? 2.0 : 5.0; });
  const Deviations e = deviations(later, leader);
  EXPECT_NEAR(e.abs_speed_mps.avg, 3.0 * 20 / 181, 1e-12);
  EXPECT_EQ(e.abs_speed_mps.max, 3.0);
  EXPECT_NEAR(e.rel_speed.avg, 0.6 * 20 / 181, 1e-12);
  EXPECT_NEAR(e.rel_speed.max, 0.6, 1e-12);
}

// Where the leader crawls (below 0.5 m/s) a relative deviation means nothing: m_rs skips those
// samples, m_as keeps them.
TEST(Deviations, ASlowLeaderIsLeftOutOfTheRelativeSpeedDeviation) {
  const auto crawl = [](double x) { return x >= 50 && x < 60 ? 0.2 : 5.0; };
  const Trajectory leader = straight(0, 100, 0, crawl);
  const Trajectory follower = straight(0, 100, 0, constant(5));
  const Deviations d = deviations(follower, leader);
  EXPECT_EQ(d.abs_speed_mps.samples, 181u);
  EXPECT_EQ(d.rel_speed.samples, 161u);  // 50, 50.5, ..., 59.5 m left out
  EXPECT_NEAR(d.abs_speed_mps.avg, 4.8 * 20 / 181, 1e-12);
  expect_zero(d.rel_speed);
}

TEST(Deviations, EmptyOrStandingTracksGiveNoSamples) {
  const Trajectory moving = straight(0, 100, 0, constant(5));
  EXPECT_EQ(deviations({}, moving).samples, 0u);
  EXPECT_EQ(deviations(moving, {}).samples, 0u);
  const Trajectory standing(100, TrajectoryPoint{0.0, Vec2(0, 0), 0.0});
  const Deviations d = deviations(moving, standing);
  EXPECT_EQ(d.samples, 0u);
  EXPECT_EQ(d.leader_segment_m, 0.0);
  EXPECT_THROW(deviations(moving, moving, {.spacing_m = 0.0}), std::invalid_argument);
}

TEST(Deviations, SamplingSpacingIsASetting) {
  const Trajectory t = straight(0, 100, 0, constant(5));
  EXPECT_EQ(deviations(t, t, {.spacing_m = 2.0}).samples, 51u);
  EXPECT_EQ(deviations(t, t, {.spacing_m = 0.3}).samples, 334u);  // 0, 0.3, ..., 99.9 m
}

// Recorded positions are sums of small steps: a 100 m track may measure a rounding error short
// of 100 m, and its end still gets its sample.
TEST(Deviations, TheEndSampleSurvivesRounding) {
  Trajectory t;
  double x = 0.0;
  for (int i = 0; i <= 1000; ++i, x += 0.1) t.push_back({0.01 * i, Vec2(x, 0), 5.0});
  const Deviations d = deviations(t, t);
  ASSERT_LT(d.leader_segment_m, 100.0);
  EXPECT_NEAR(d.leader_segment_m, 100.0, 1e-9);
  EXPECT_EQ(d.samples, 201u);
}

// The series behind the averages: one entry per sample at k * spacing along the leader, with
// the distance and both speeds there; its mean and maximum are the metrics.
TEST(Deviations, TheSeriesHoldsEverySampleAlongTheLeadersPath) {
  const auto v = [](double x) { return 2.0 + 0.05 * x; };
  const Trajectory leader = straight(0, 100, 0, v);
  const Trajectory follower = straight(0, 100, 0.4, [&](double x) { return 0.5 * v(x); });
  const Deviations d = deviations(follower, leader);
  ASSERT_EQ(d.series.size(), d.samples);
  ASSERT_EQ(d.series.size(), 201u);
  double sum = 0.0;
  for (std::size_t k = 0; k < d.series.size(); ++k) {
    const Sample& s = d.series[k];
    EXPECT_EQ(s.arc_m, 0.5 * static_cast<double>(k));
    EXPECT_NEAR(s.path_m, 0.4, 1e-12);
    EXPECT_NEAR(s.leader_speed_mps, v(s.arc_m), 1e-12);
    EXPECT_NEAR(s.follower_speed_mps, 0.5 * v(s.arc_m), 1e-12);
    sum += s.path_m;
  }
  EXPECT_NEAR(sum / 201.0, d.path_m.avg, 1e-12);
  EXPECT_TRUE(deviations({}, leader).series.empty());
}

// A vehicle that stands 2 s, drives 100 m in 20 s (5 m/s) and stands 3 s: 5 m/s moving, not
// 100 m / 25 s; the maximum is the fastest frame.
TEST(SpeedSummary, MeanOverTheTimeMovingAndTheMaximum) {
  Trajectory t;
  double time = 0.0;
  for (int i = 0; i < 200; ++i, time += 0.01) t.push_back({time, Vec2(0, 0), 0.0});
  for (int i = 0; i <= 400; ++i, time += 0.05) {
    t.push_back({time, Vec2(0.25 * i, 0), i == 200 ? 5.5 : 5.0});
  }
  for (int i = 0; i < 300; ++i, time += 0.01) t.push_back({time, Vec2(100, 0), 0.0});
  const SpeedSummary s = speed_summary(t);
  EXPECT_NEAR(s.mean_moving_mps, 5.0, 1e-9);
  EXPECT_EQ(s.max_mps, 5.5);
  EXPECT_NEAR(s.distance_m, 100.0, 1e-12);
  // Never as fast as the threshold: no mean.
  const Trajectory crawl = straight(0, 10, 0, constant(0.3));
  EXPECT_EQ(speed_summary(crawl).mean_moving_mps, 0.0);
  EXPECT_EQ(speed_summary({}).max_mps, 0.0);
}

TEST(Chains, FollowersAreComparedWithTheHeadOfTheirChain) {
  const auto c = resolve_chains({{"f1", "l1"}, {"f2", "f1"}, {"f3", "f2"}, {"g1", "l2"}});
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(c.at("f1").leader, "l1");
  EXPECT_EQ(c.at("f1").follows, "l1");
  EXPECT_EQ(c.at("f1").position, 1);
  EXPECT_EQ(c.at("f2").leader, "l1");
  EXPECT_EQ(c.at("f2").follows, "f1");
  EXPECT_EQ(c.at("f2").position, 2);
  EXPECT_EQ(c.at("f3").leader, "l1");
  EXPECT_EQ(c.at("f3").position, 3);
  EXPECT_EQ(c.at("g1").leader, "l2");
  EXPECT_EQ(c.at("g1").position, 1);
}

TEST(Chains, ACycleIsAnErrorNamingIt) {
  try {
    resolve_chains({{"a", "b"}, {"b", "a"}});
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("a -> b -> a"), std::string::npos) << e.what();
  }
}
