// The follower fed directly (open loop): lost and found leaders, stale messages, conversions.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "convoy/follower.hpp"
#include "sensors/interoceptive.hpp"

using namespace syndds;
using namespace syndds::convoy;

namespace {

const sensors::Geodetic kOrigin{43.07, -89.4, 260.0};

// Drives an ideal straight-line world: the follower at x = -15 + v t, the leader at x = v t,
// both heading east at `v`; readings are exact (no noise), 10 Hz GPS, 100 Hz the rest.
struct StraightWorld {
  sensors::GeodeticConverter converter{kOrigin, sensors::GeodeticModel::wgs84};
  double v = 5.0;
  double radius = 0.5;

  OwnReadings own(double t) const {
    OwnReadings r;
    proto::GpsFixMsg g;
    const auto geo = converter.to_geodetic(Vec3(-15.0 + v * t, 0.0, 0.0));
    g.latitude_deg = geo.lat_deg;
    g.longitude_deg = geo.lon_deg;
    g.altitude_m = geo.alt_m;
    g.stamp.time_s = t;
    r.gps.push_back(g);
    proto::MagnetometerMsg m;
    m.heading_rad = std::numbers::pi / 2.0;  // east
    r.compass.push_back(m);
    proto::WheelSpeedsMsg w;
    w.wheel_spin_rad_s.assign(4, v / radius);
    r.wheel_speeds.push_back(w);
    return r;
  }
  proto::V2VMessageMsg leader(double t, std::uint64_t seq) const {
    proto::V2VMessageMsg m;
    m.vehicle_id = "l1";
    m.sequence = seq;
    m.sensor_time_s = t;
    const auto geo = converter.to_geodetic(Vec3(v * t, 0.0, 0.0));
    m.latitude_deg = geo.lat_deg;
    m.longitude_deg = geo.lon_deg;
    m.altitude_m = geo.alt_m;
    m.speed_mps = v;
    m.heading_rad = std::numbers::pi / 2.0;
    return m;
  }
};

FollowerConfig config() {
  FollowerConfig c;
  c.leader = "l1";
  c.leader_lost_after_s = 1.0;
  return c;
}

}  // namespace

TEST(Follower, HeadingConversionIsCompassToMathAngle) {
  EXPECT_NEAR(yaw_from_heading(0.0), std::numbers::pi / 2.0, 1e-12);        // north
  EXPECT_NEAR(yaw_from_heading(std::numbers::pi / 2.0), 0.0, 1e-12);        // east
  EXPECT_NEAR(std::abs(yaw_from_heading(3.0 * std::numbers::pi / 2.0)), std::numbers::pi, 1e-12);
}

TEST(Follower, HoldsStillUntilItKnowsWhereItAndItsLeaderAre) {
  StraightWorld w;
  ConvoyFollower f(config(), FollowerVehicle{3.378, 0.53, w.radius}, w.converter);
  std::vector<FollowerEvent> events;
  const auto cmd = f.update(0.0, 0.01, {}, {}, events);
  EXPECT_EQ(cmd.braking, 1.0);
  EXPECT_EQ(cmd.throttle, 0.0);
  EXPECT_FALSE(f.ready());
}

TEST(Follower, LosesTheLeaderOnceBrakesAndFindsItAgain) {
  StraightWorld w;
  ConvoyFollower f(config(), FollowerVehicle{3.378, 0.53, w.radius}, w.converter);
  std::vector<FollowerEvent> events;
  std::uint64_t seq = 0;
  auto step = [&](int k, bool link) {
    const double t = k * 0.01;
    std::vector<proto::V2VMessageMsg> msgs;
    if (link && k % 10 == 0) msgs.push_back(w.leader(t, seq++));
    OwnReadings own = w.own(t);
    if (k % 10 != 0) own.gps.clear();  // GPS at 10 Hz
    return f.update(t, 0.01, own, msgs, events);
  };
  for (int k = 0; k < 500; ++k) step(k, true);  // 5 s following at 5 m/s
  EXPECT_TRUE(events.empty());
  EXPECT_FALSE(f.leader_lost());
  EXPECT_GT(f.target_speed_mps(), 0.0);
  // The estimates agree with the ideal world: the leader 15 m ahead along the trail.
  EXPECT_NEAR(f.position_estimate().x(), -15.0 + 5.0 * 4.99, 0.1);
  EXPECT_NEAR(f.gap_m(), 15.0, 0.2);

  // Link cut: dead reckoning for leader_lost_after_s, then braking and one event.
  int lost_at = -1;
  vehicle::DriverInputs cmd;
  for (int k = 500; k < 800; ++k) {
    cmd = step(k, false);
    if (lost_at < 0 && f.leader_lost()) lost_at = k;
  }
  ASSERT_GE(lost_at, 0);
  EXPECT_NEAR((lost_at - 490) * 0.01, 1.0, 0.02);  // newest message measured at t = 4.9 s
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, "leader_lost");
  EXPECT_EQ(f.target_speed_mps(), 0.0);
  EXPECT_GT(cmd.braking, 0.0);
  EXPECT_EQ(cmd.throttle, 0.0);

  // The link is back: one leader_found, following resumes.
  for (int k = 800; k < 900; ++k) step(k, true);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[1].kind, "leader_found");
  EXPECT_FALSE(f.leader_lost());
}

TEST(Follower, IgnoresMessagesOlderThanOneItUsed) {
  StraightWorld w;
  ConvoyFollower f(config(), FollowerVehicle{3.378, 0.53, w.radius}, w.converter);
  std::vector<FollowerEvent> events;
  f.update(0.0, 0.01, w.own(0.0), {w.leader(0.0, 5)}, events);
  const Vec2 before = f.leader_estimate();
  // A replayed older message claiming the leader is 100 m back changes nothing.
  auto stale = w.leader(0.0, 4);
  const auto geo = w.converter.to_geodetic(Vec3(-100.0, 0.0, 0.0));
  stale.latitude_deg = geo.lat_deg;
  stale.longitude_deg = geo.lon_deg;
  f.update(0.0, 0.0, {}, {stale}, events);
  EXPECT_NEAR((f.leader_estimate() - before).norm(), 0.0, 1e-9);
}
