// The follower fed directly: lost and found leaders, stale messages, conversions (open loop),
// the gap law's braking-distance term, locked wheels, a standing leader's trail, the steering
// on a circle, (closed loop, a small vehicle model in the test) the understeer it learns, and
// the gap taken from its own radar.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "convoy/follower.hpp"
#include "sensors/interoceptive.hpp"

using namespace syndds;
using namespace syndds::convoy;

namespace {

const sensors::Geodetic kOrigin{43.07, -89.4, 260.0};
const sensors::GeodeticConverter kConverter{kOrigin, sensors::GeodeticModel::wgs84};
constexpr double kRadius = 0.5;  // wheel radius of the test vehicles

// The vehicle: HMMWV dimensions, the reduced model's steering (input = bicycle angle / max).
FollowerVehicle test_vehicle() {
  FollowerVehicle v;
  v.wheel_radius_m = kRadius;
  v.inner_wheel_input = false;
  return v;
}

FollowerConfig config() {
  FollowerConfig c;
  c.leader = "l1";
  c.leader_lost_after_s = 1.0;
  return c;
}

double heading_of(double yaw) { return std::numbers::pi / 2.0 - yaw; }  // compass, from north

// Exact readings of a vehicle at `p` with body yaw `yaw` and speed `v`, measured at `t`.
OwnReadings readings(double t, const Vec2& p, double yaw, double v, bool gps) {
  OwnReadings r;
  if (gps) {
    proto::GpsFixMsg g;
    const auto geo = kConverter.to_geodetic(Vec3(p.x(), p.y(), 0.0));
    g.latitude_deg = geo.lat_deg;
    g.longitude_deg = geo.lon_deg;
    g.altitude_m = geo.alt_m;
    g.stamp.time_s = t;
    r.gps.push_back(g);
  }
  proto::MagnetometerMsg m;
  m.heading_rad = heading_of(yaw);
  m.stamp.time_s = t;
  r.compass.push_back(m);
  proto::WheelSpeedsMsg w;
  w.wheel_spin_rad_s.assign(4, v / kRadius);
  r.wheel_speeds.push_back(w);
  return r;
}

proto::V2VMessageMsg message(double t, std::uint64_t seq, const Vec2& p, double yaw, double v) {
  proto::V2VMessageMsg m;
  m.vehicle_id = "l1";
  m.sequence = seq;
  m.sensor_time_s = t;
  const auto geo = kConverter.to_geodetic(Vec3(p.x(), p.y(), 0.0));
  m.latitude_deg = geo.lat_deg;
  m.longitude_deg = geo.lon_deg;
  m.altitude_m = geo.alt_m;
  m.speed_mps = v;
  m.heading_rad = heading_of(yaw);
  return m;
}

// An ideal straight-line world: the follower at x = -15 + v t, the leader at x = v t, both
// heading east at `v`; readings are exact, 10 Hz GPS and V2V, 100 Hz the rest.
struct StraightWorld {
  double v = 5.0;
  OwnReadings own(double t) const { return readings(t, Vec2(-15.0 + v * t, 0.0), 0.0, v, true); }
  proto::V2VMessageMsg leader(double t, std::uint64_t seq) const {
    return message(t, seq, Vec2(v * t, 0.0), 0.0, v);
  }
};

// 10 s of StraightWorld at 100 Hz (GPS and V2V at 10 Hz): the follower ends at x = 35 on
// the trail (y = 0), the leader at x = 50. Returns the last command.
vehicle::DriverInputs drive_straight_world(ConvoyFollower& f) {
  std::vector<FollowerEvent> events;
  std::uint64_t seq = 0;
  vehicle::DriverInputs cmd;
  const StraightWorld world;
  for (int k = 0; k <= 1000; ++k) {
    const double t = k * 0.01;
    std::vector<proto::V2VMessageMsg> msgs;
    if (k % 10 == 0) msgs.push_back(world.leader(t, seq++));
    OwnReadings own = world.own(t);
    if (k % 10 != 0) own.gps.clear();
    cmd = f.update(t, 0.01, own, msgs, events);
  }
  return cmd;
}

// The kinematic road-wheel angle that drives the mid-wheelbase point on radius r.
double kinematic_angle(double r, double wheelbase) {
  return std::atan(wheelbase / std::sqrt(r * r - 0.25 * wheelbase * wheelbase));
}

}  // namespace

TEST(Follower, HeadingConversionIsCompassToMathAngle) {
  EXPECT_NEAR(yaw_from_heading(0.0), std::numbers::pi / 2.0, 1e-12);        // north
  EXPECT_NEAR(yaw_from_heading(std::numbers::pi / 2.0), 0.0, 1e-12);        // east
  EXPECT_NEAR(std::abs(yaw_from_heading(3.0 * std::numbers::pi / 2.0)), std::numbers::pi, 1e-12);
}

TEST(Follower, HoldsStillUntilItKnowsWhereItAndItsLeaderAre) {
  ConvoyFollower f(config(), test_vehicle(), kConverter);
  std::vector<FollowerEvent> events;
  const auto cmd = f.update(0.0, 0.01, {}, {}, events);
  EXPECT_EQ(cmd.braking, 1.0);
  EXPECT_EQ(cmd.throttle, 0.0);
  EXPECT_FALSE(f.ready());
}

TEST(Follower, LosesTheLeaderOnceBrakesAndFindsItAgain) {
  StraightWorld w;
  ConvoyFollower f(config(), test_vehicle(), kConverter);
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
  // The estimates agree with the ideal world: the leader 15 m ahead centre to centre, the
  // bumpers 15 - 2.35 - 2.35 m apart.
  EXPECT_NEAR(f.position_estimate().x(), -15.0 + 5.0 * 4.99, 0.1);
  EXPECT_NEAR(f.gap_m(), 10.3, 0.2);
  // A leader at constant speed: the desired gap is standstill + time gap * speed.
  EXPECT_NEAR(f.desired_gap_m(), 5.0 + 1.0 * 5.0, 1e-6);

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
  ConvoyFollower f(config(), test_vehicle(), kConverter);
  std::vector<FollowerEvent> events;
  f.update(0.0, 0.01, w.own(0.0), {w.leader(0.0, 5)}, events);
  const Vec2 before = f.leader_estimate();
  // A replayed older message claiming the leader is 100 m back changes nothing.
  auto stale = message(0.0, 4, Vec2(-100.0, 0.0), 0.0, 5.0);
  f.update(0.0, 0.0, {}, {stale}, events);
  EXPECT_NEAR((f.leader_estimate() - before).norm(), 0.0, 1e-9);
}

// The leader brakes at 6 m/s2 from 8 m/s, harder than the 4 m/s2 the follower counts on for
// itself; the follower (at 8 m/s, 13 m of bumper gap: its cruise gap) adds the difference of
// the two braking distances to its desired gap and brakes fully at once.
TEST(Follower, ABrakingLeaderAddsTheDifferenceOfTheBrakingDistances) {
  ConvoyFollower f(config(), test_vehicle(), kConverter);
  std::vector<FollowerEvent> events;
  const double v = 8.0, brake_at = 5.0, decel = 6.0;
  double leader_x = 0.0, leader_v = v;
  std::uint64_t seq = 0;
  vehicle::DriverInputs cmd;
  for (int k = 0; k <= 530; ++k) {
    const double t = k * 0.01;
    if (t > brake_at + 1e-9) leader_v = std::max(0.0, leader_v - decel * 0.01);
    leader_x += leader_v * 0.01;
    std::vector<proto::V2VMessageMsg> msgs;
    if (k % 10 == 0) msgs.push_back(message(t, seq++, Vec2(leader_x, 0.0), 0.0, leader_v));
    // The follower is driven open loop at 8 m/s, 17.7 m centre to centre behind at first.
    cmd = f.update(t, 0.01, readings(t, Vec2(v * t - 17.7, 0.0), 0.0, v, k % 10 == 0), msgs,
                   events);
    if (k == 490) {
      EXPECT_NEAR(f.leader_accel_mps2(), 0.0, 1e-9);
      EXPECT_NEAR(f.desired_gap_m(), 5.0 + 8.0, 1e-9);  // cruising: no braking term
      EXPECT_LT(cmd.braking, 0.05);
    }
  }
  // Messages at 5.1, 5.2 and 5.3 s told speeds 7.4, 6.8, 6.2 m/s: 6 m/s2.
  EXPECT_NEAR(f.leader_accel_mps2(), -decel, 1e-6);
  const double v_leader = 8.0 - 6.0 * 0.3;
  const double extra = v * v / (2.0 * 4.0) - v_leader * v_leader / (2.0 * decel);
  EXPECT_NEAR(f.desired_gap_m(), 5.0 + 8.0 + extra, 1e-6);
  EXPECT_EQ(cmd.braking, 1.0);
  EXPECT_EQ(cmd.throttle, 0.0);
}

// Locked wheels read 0 while the vehicle slides: the speed estimate falls at most 9 m/s2.
TEST(Follower, LockedWheelsDoNotStopTheSpeedEstimate) {
  StraightWorld w;
  w.v = 8.0;
  ConvoyFollower f(config(), test_vehicle(), kConverter);
  std::vector<FollowerEvent> events;
  std::uint64_t seq = 0;
  for (int k = 0; k < 100; ++k) {
    const double t = k * 0.01;
    std::vector<proto::V2VMessageMsg> msgs;
    if (k % 10 == 0) msgs.push_back(w.leader(t, seq++));
    f.update(t, 0.01, w.own(t), msgs, events);
  }
  const Vec2 before = f.position_estimate();
  for (int k = 100; k < 110; ++k) {
    OwnReadings own = w.own(k * 0.01);
    own.gps.clear();
    own.wheel_speeds[0].wheel_spin_rad_s.assign(4, 0.0);  // locked
    f.update(k * 0.01, 0.01, own, {}, events);
  }
  // 10 updates at 9 m/s2: 8 - 0.9 m/s, and the estimate moved on by the sum of the speeds.
  double moved = 0.0;
  for (int i = 1; i <= 10; ++i) moved += (8.0 - 0.09 * (i - 1)) * 0.01;
  EXPECT_NEAR(f.position_estimate().x() - before.x(), moved, 1e-9);
}

// A standing leader's estimate wanders with its GPS noise: it lays no crumbs, so the trail (and
// the gap measured along it) does not grow.
TEST(Follower, AStandingLeaderLaysNoCrumbs) {
  ConvoyFollower f(config(), test_vehicle(), kConverter);
  std::vector<FollowerEvent> events;
  std::uint64_t seq = 0;
  for (int k = 0; k < 3000; ++k) {
    const double t = k * 0.01;
    std::vector<proto::V2VMessageMsg> msgs;
    if (k % 10 == 0) {
      // Fixes jumping +-0.8 m around x = 0 (GPS noise), the leader standing.
      const double jump = (seq % 2 == 0 ? 0.8 : -0.8) * (seq % 3 == 0 ? 1.0 : 0.5);
      msgs.push_back(message(t, seq++, Vec2(jump, 0.6 * jump), 0.0, 0.0));
    }
    f.update(t, 0.01, readings(t, Vec2(-12.0, 0.0), 0.0, 0.0, k % 10 == 0), msgs, events);
  }
  EXPECT_EQ(f.trail().size(), 1u);  // the follower's own start only
  EXPECT_LT(std::abs(f.gap_m() - (12.0 - 4.7)), 1.0);
}

// A straight lead-in, then a circle of radius 20 m, at 5 m/s, exact readings of both, the
// follower 15 m behind on the same path: the trail's curvature alone steers it on the circle
// (no heading or cross-track error): the kinematic angle of the mid-wheelbase point on 20 m,
// plus the understeer term.
TEST(Follower, OnACircleTheCurvatureOfTheTrailSteers) {
  const double r = 20.0, v = 5.0;
  const FollowerVehicle veh = test_vehicle();
  // The mid-wheelbase point moves at asin(L / 2 / R) inside the body's heading.
  const double slip = std::asin(0.5 * veh.wheelbase_m / r);
  // Arc position s: on the lead-in (s < 0) eastwards along y = -r, then counter-clockwise
  // round the origin; the position and the body's yaw.
  const auto path = [&](double s) {
    if (s < 0.0) return std::pair{Vec2(s, -r), 0.0};
    const double a = s / r;
    return std::pair{Vec2(r * std::sin(a), -r * std::cos(a)), a - slip};
  };
  ConvoyFollower f(config(), veh, kConverter);
  std::vector<FollowerEvent> events;
  std::uint64_t seq = 0;
  vehicle::DriverInputs cmd;
  for (int k = 0; k <= 3000; ++k) {
    const double t = k * 0.01;
    const auto [lp, lyaw] = path(v * t - 10.0);
    const auto [fp, fyaw] = path(v * t - 25.0);
    std::vector<proto::V2VMessageMsg> msgs;
    if (k % 10 == 0) msgs.push_back(message(t, seq++, lp, lyaw, v));
    cmd = f.update(t, 0.01, readings(t, fp, fyaw, v, k % 10 == 0), msgs, events);
  }
  EXPECT_NEAR(f.cross_track_m(), 0.0, 0.02);
  // Open loop the follower's steering does not turn it, so the understeer it learns is
  // whatever it starts with (the turn-in's transient): the feed-forward is the kinematic angle
  // plus that understeer times the lateral acceleration.
  const double angle =
      kinematic_angle(r, veh.wheelbase_m) + f.understeer_rad_per_mps2() * v * v / r;
  EXPECT_NEAR(cmd.steering, angle / veh.max_steer_rad, 0.01);
}

// On a straight line 0.5 m right of the leader's track, heading parallel to it: the follower
// steers left by atan(k e / (v + 1)) (Stanley, k = 1 /s).
TEST(Follower, BesideTheTrailItSteersBackByTheCrossTrackGain) {
  const double v = 5.0;
  const FollowerVehicle veh = test_vehicle();
  ConvoyFollower f(config(), veh, kConverter);
  std::vector<FollowerEvent> events;
  std::uint64_t seq = 0;
  vehicle::DriverInputs cmd;
  for (int k = 0; k <= 1000; ++k) {
    const double t = k * 0.01;
    std::vector<proto::V2VMessageMsg> msgs;
    if (k % 10 == 0) msgs.push_back(message(t, seq++, Vec2(v * t, 0.0), 0.0, v));
    cmd = f.update(t, 0.01, readings(t, Vec2(v * t - 15.0, -0.5), 0.0, v, k % 10 == 0), msgs,
                   events);
  }
  EXPECT_NEAR(f.cross_track_m(), -0.5, 0.01);
  EXPECT_NEAR(cmd.steering, std::atan(0.5 / (v + 1.0)) / veh.max_steer_rad, 0.01);
}

// A map of obstacles (KeepOut, the learned follower's teacher): on a straight trail, the
// follower tracks the trail shifted away from an obstacle whose edge comes closer than the
// clearance, by the difference; obstacles on both sides push against each other; the shift
// ramps in before an obstacle and ends past it. The trail, the cross-track estimate and the
// trail features do not change; without a map the command is the same as ever.
TEST(Follower, AMapOfObstaclesShiftsTheTrackedTrailAwayFromThem) {
  const double v = 5.0;
  const FollowerVehicle veh = test_vehicle();
  // The follower ends at x = 35 on the trail (y = 0), the leader at x = 50.
  struct Result {
    double shift, steering, cross_track, feature_cross_track;
  };
  const auto run = [&](std::vector<KeepOut::Circle> obstacles) {
    ConvoyFollower f(config(), veh, kConverter);
    KeepOut keep_out;
    keep_out.obstacles = std::move(obstacles);
    f.set_keep_out(keep_out);
    const vehicle::DriverInputs cmd = drive_straight_world(f);
    return Result{f.keep_out_shift_m(), cmd.steering, f.cross_track_m(),
                  f.trail_features().cross_track_m};
  };
  const double wanted = KeepOut{}.clearance_m;  // 2.5 m
  // Stanley on the shifted trail: atan(k (cross-track - shift) / (v + 1)), k = 1.
  const auto steering_for = [&](double shift) {
    return -std::atan(-shift / (v + 1.0)) / veh.max_steer_rad;
  };

  const Result none = run({});
  EXPECT_EQ(none.shift, 0.0);
  EXPECT_NEAR(none.steering, 0.0, 1e-3);

  // Edge 1.5 m left of the trail: shifted 1 m to the right.
  const Result left = run({{Vec2(35.0, 2.5), 1.0}});
  EXPECT_NEAR(left.shift, -(wanted - 1.5), 1e-9);
  EXPECT_NEAR(left.steering, steering_for(left.shift), 1e-3);
  EXPECT_LT(left.steering, -0.1);  // to the right, away from it
  EXPECT_NEAR(left.cross_track, none.cross_track, 1e-12);
  EXPECT_NEAR(left.feature_cross_track, none.feature_cross_track, 1e-12);

  // And a second, 2.0 m right of the trail, pushing back by 0.5 m.
  const Result both = run({{Vec2(35.0, 2.5), 1.0}, {Vec2(35.0, -3.0), 1.0}});
  EXPECT_NEAR(both.shift, (wanted - 2.0) - (wanted - 1.5), 1e-9);

  // Far enough from the trail: nothing.
  EXPECT_EQ(run({{Vec2(35.0, 4.0), 1.0}}).shift, 0.0);
  // The ramp: the shift starts lead_in_m (8 m) before the obstacle's edge and is full ramp_m
  // (4 m) later; it ends 2 m past the obstacle.
  EXPECT_EQ(run({{Vec2(35.0 + 1.0 + 8.0 + 0.5, 2.5), 1.0}}).shift, 0.0);
  EXPECT_NEAR(run({{Vec2(35.0 + 1.0 + 8.0 - 2.0, 2.5), 1.0}}).shift, -0.5, 1e-9);
  EXPECT_NEAR(run({{Vec2(35.0 - 1.0 - 1.5, 2.5), 1.0}}).shift, -1.0, 1e-9);
  EXPECT_EQ(run({{Vec2(35.0 - 1.0 - 2.5, 2.5), 1.0}}).shift, 0.0);
  // A big shift is capped.
  EXPECT_NEAR(run({{Vec2(35.0, 0.5), 1.0}}).shift, -KeepOut{}.max_shift_m, 1e-9);
}

// What a follower with a camera sees of the map (KeepOut::in_view): a 90 degree view from a
// camera 2.4 m ahead of the reference point, along the heading. A circle counts when any part
// of it is inside the wedge and in front of the camera.
TEST(Follower, TheMapsViewIsTheCamerasWedge) {
  KeepOut k;
  const Vec2 at(10.0, 5.0);
  const double yaw = std::numbers::pi / 2.0;  // heading north: ahead is +y, left is -x
  const auto seen = [&](double ahead, double left, double radius) {
    // The circle `ahead` m in front of the camera and `left` m to its left.
    return k.in_view({at + Vec2(0.0, 2.4 + ahead) + Vec2(-left, 0.0), radius}, at, yaw);
  };
  // Without a view every obstacle counts, wherever it is.
  EXPECT_TRUE(seen(-20.0, 0.0, 1.0));
  k.view_half_angle_rad = std::numbers::pi / 4.0;
  k.view_ahead_m = 2.4;
  EXPECT_TRUE(seen(5.0, 0.0, 0.5));     // straight ahead
  EXPECT_TRUE(seen(5.0, 4.9, 0.1));     // just inside the edge on the left ...
  EXPECT_TRUE(seen(5.0, -4.9, 0.1));    // ... and on the right
  EXPECT_FALSE(seen(5.0, 5.2, 0.1));    // just outside
  EXPECT_TRUE(seen(5.0, 5.2, 0.5));     // its centre outside, its edge inside (0.14 m away)
  EXPECT_FALSE(seen(2.0, 3.5, 1.0));    // beside the bonnet: 1.06 m from the edge
  EXPECT_TRUE(seen(2.0, 3.5, 1.1));
  EXPECT_FALSE(seen(-1.5, 0.0, 1.0));   // behind the camera
  EXPECT_TRUE(seen(-0.5, 0.0, 1.0));    // its front half before it
  EXPECT_FALSE(seen(-0.8, 0.5, 0.9));   // behind and beside: the camera is its nearest point
  EXPECT_TRUE(seen(-0.8, 0.5, 1.0));    // (0.94 m away)
}

// A teacher whose map is limited to the camera's view keeps clear only of what it sees now:
// the obstacle of the map test above (edge 1.5 m left of the trail, centre level with the
// follower's reference point) is beside the vehicle, out of a forward camera's view, so no
// shift; the same obstacle 5 m further on is in view and shifts the trail as a whole map does.
TEST(Follower, AMapLimitedToTheCamerasViewShiftsOnlyForWhatItSees) {
  const FollowerVehicle veh = test_vehicle();
  const auto shift = [&](double view_half_angle, Vec2 centre) {
    ConvoyFollower f(config(), veh, kConverter);
    KeepOut keep_out;
    keep_out.obstacles = {{centre, 1.0}};
    keep_out.view_half_angle_rad = view_half_angle;
    keep_out.view_ahead_m = 2.4;
    f.set_keep_out(keep_out);
    drive_straight_world(f);
    return f.keep_out_shift_m();
  };
  const double wanted = KeepOut{}.clearance_m;
  EXPECT_NEAR(shift(0.0, Vec2(35.0, 2.5)), -(wanted - 1.5), 1e-9);
  EXPECT_EQ(shift(std::numbers::pi / 4.0, Vec2(35.0, 2.5)), 0.0);
  EXPECT_NEAR(shift(0.0, Vec2(40.0, 2.5)), -(wanted - 1.5), 1e-9);
  EXPECT_NEAR(shift(std::numbers::pi / 4.0, Vec2(40.0, 2.5)), -(wanted - 1.5), 1e-9);
}

// Closed loop with a vehicle that understeers (0.03 rad of road-wheel angle per m/s2, soft
// ground): behind a leader on a 15 m circle, the follower learns the understeer from its own
// compass and steering and stays on the leader's circle. Without it, it would run about
// 0.03 * 1.7 m/s2 * 6 m/s / 1 = 0.3 m outside.
TEST(Follower, LearnsTheUndersteerOfItsVehicle) {
  const double r = 15.0, v = 5.0, understeer = 0.03;
  const FollowerVehicle veh = test_vehicle();
  const double l = veh.wheelbase_m;
  ConvoyFollower f(config(), veh, kConverter);
  std::vector<FollowerEvent> events;
  // The follower's vehicle: the mid-wheelbase point at `p`, body yaw `yaw`, constant speed;
  // the road-wheel angle `delta` turns it on the curvature k with delta = kin(k) + K v^2 k.
  Vec2 p(r, -15.0);  // on the circle's tangent line, 15 m of arc behind (close enough)
  double yaw = std::numbers::pi / 2.0;
  double delta = 0.0;
  std::uint64_t seq = 0;
  double worst_late = 0.0;
  for (int k = 0; k <= 4000; ++k) {
    const double t = k * 0.01;
    const double a = v * t / r;
    const double lslip = std::asin(0.5 * l / r);
    std::vector<proto::V2VMessageMsg> msgs;
    if (k % 10 == 0) {
      msgs.push_back(message(t, seq++, Vec2(r * std::cos(a), r * std::sin(a)),
                             a + std::numbers::pi / 2.0 - lslip, v));
    }
    const auto cmd = f.update(t, 0.01, readings(t, p, yaw, v, k % 10 == 0), msgs, events);
    delta = cmd.steering * veh.max_steer_rad;
    // Curvature from the road-wheel angle: solve delta = kin(k) + K v^2 k by fixed point.
    double curvature = 0.0;
    for (int i = 0; i < 50; ++i) {
      const double kin = delta - understeer * v * v * curvature;
      const double r_rear = l / std::tan(std::abs(kin) + 1e-12);
      curvature = std::copysign(1.0 / std::sqrt(r_rear * r_rear + 0.25 * l * l), kin);
    }
    const double slip = std::asin(0.5 * l * curvature);
    p += v * 0.01 * Vec2(std::cos(yaw + slip), std::sin(yaw + slip));
    yaw += v * curvature * 0.01;
    if (t > 30.0) worst_late = std::max(worst_late, std::abs(p.norm() - r));
  }
  EXPECT_NEAR(f.understeer_rad_per_mps2(), understeer, 0.006);
  EXPECT_LT(worst_late, 0.1);
}

// With `radar.sensor`, the nearest detection of that radar in the follower's lane, close to the
// V2V gap and fresh, gives the gap (carried to now by its range rate); any other detection is
// ignored and the V2V gap stays.
TEST(Follower, AnInLaneRadarDetectionGivesTheGap) {
  FollowerConfig c = config();
  c.radar_sensor = "front_radar";
  FollowerVehicle vehicle = test_vehicle();
  vehicle.radar_ahead_of_front_m = 0.05;
  const StraightWorld w;
  auto scan = [](const std::string& sensor, double t, float x, float y, float rate) {
    proto::RadarScanMsg s;
    s.stamp.sensor_id = sensor;
    s.stamp.time_s = t;
    proto::RadarDetectionMsg d;
    d.x = x;
    d.y = y;
    d.radial_speed_mps = rate;
    s.detections.push_back(d);
    return s;
  };
  struct Case {
    const char* name;
    proto::RadarScanMsg scan;
    bool used;
    double gap;
  };
  const double t = 3.0;
  const double v2v_gap = 15.0 - 2.35 - 2.35;
  const std::vector<Case> cases = {
      {"in lane", scan("front_radar", t, 9.0f, 0.2f, -1.0f), true, 9.05},
      {"carried to now", scan("front_radar", t - 0.1, 9.0f, 0.2f, -1.0f), true, 8.95},
      {"out of lane", scan("front_radar", t, 9.0f, 2.0f, -1.0f), false, v2v_gap},
      {"beyond the gate", scan("front_radar", t, 5.0f, 0.0f, 0.0f), false, v2v_gap},
      {"stale", scan("front_radar", t - 0.5, 9.0f, 0.0f, 0.0f), false, v2v_gap},
      {"another radar", scan("rear_radar", t, 9.0f, 0.0f, 0.0f), false, v2v_gap},
  };
  for (const auto& k : cases) {
    SCOPED_TRACE(k.name);
    ConvoyFollower f(c, vehicle, kConverter);
    std::vector<FollowerEvent> events;
    std::uint64_t seq = 0;
    for (int i = 0; i < 300; ++i) {
      const double ti = i * 0.01;
      std::vector<proto::V2VMessageMsg> msgs;
      if (i % 10 == 0) msgs.push_back(w.leader(ti, seq++));
      f.update(ti, 0.01, w.own(ti), msgs, events);
    }
    EXPECT_FALSE(f.radar_in_use());
    EXPECT_NEAR(f.gap_m(), v2v_gap, 0.05);
    f.observe_radar({k.scan});
    f.update(t, 0.01, w.own(t), {w.leader(t, seq++)}, events);
    EXPECT_EQ(f.radar_in_use(), k.used);
    EXPECT_NEAR(f.gap_m(), k.gap, 0.05);
    if (k.used) {
      // The leader's speed from the range rate (own 5 m/s, closing at 1 m/s): 4 m/s, and the
      // gap short of the 10 m desired: the target is below the leader's speed.
      EXPECT_LT(f.target_speed_mps(), 4.0);
    }
  }
}

// trail_of: the head h1 drives y = 0, the leader l1 (the vehicle followed) 0.5 m left of it,
// the follower on y = 0, all at 5 m/s heading east, the follower 15 m behind the leader and 30 m
// behind the head. Steering along the head's trail it has no cross-track error and steers
// straight on; along the leader's it steers towards the leader's offset. Its spacing is to the
// leader either way. A silent head is a lost leader (named), and the state round-trips.
TEST(Follower, AlongTheHeadsTrailItSteersOnTheHeadsTrackAndKeepsItsGapToTheLeader) {
  const double v = 5.0;
  const FollowerVehicle veh = test_vehicle();
  auto from = [](proto::V2VMessageMsg m, const std::string& id) {
    m.vehicle_id = id;
    return m;
  };
  // Runs 10 s (the head silent from `head_silent_s`); returns the last command.
  auto run = [&](ConvoyFollower& f, std::vector<FollowerEvent>& events, double head_silent_s,
                 int from_k, int to_k) {
    vehicle::DriverInputs cmd;
    for (int k = from_k; k <= to_k; ++k) {
      const double t = k * 0.01;
      std::vector<proto::V2VMessageMsg> msgs;
      if (k % 10 == 0) {
        const auto seq = static_cast<std::uint64_t>(k / 10);
        msgs.push_back(message(t, seq, Vec2(v * t, 0.5), 0.0, v));  // l1
        if (t < head_silent_s) msgs.push_back(from(message(t, seq, Vec2(v * t + 15.0, 0.0), 0.0, v), "h1"));
      }
      cmd = f.update(t, 0.01, readings(t, Vec2(v * t - 15.0, 0.0), 0.0, v, k % 10 == 0), msgs,
                     events);
    }
    return cmd;
  };
  FollowerConfig head = config();
  head.trail_of = "h1";
  ConvoyFollower along_head(head, veh, kConverter);
  ConvoyFollower along_leader(config(), veh, kConverter);
  std::vector<FollowerEvent> events;
  const auto cmd_head = run(along_head, events, 1e9, 0, 1000);
  const auto cmd_leader = run(along_leader, events, 1e9, 0, 1000);
  EXPECT_TRUE(events.empty());
  EXPECT_NEAR(along_head.cross_track_m(), 0.0, 0.01);
  EXPECT_NEAR(cmd_head.steering, 0.0, 0.002);
  EXPECT_NEAR(along_leader.cross_track_m(), -0.5, 0.01);
  EXPECT_NEAR(cmd_leader.steering, std::atan(0.5 / (v + 1.0)) / veh.max_steer_rad, 0.01);
  // The trail reaches the head (30 m ahead), the gap is the leader's: 15 m less the bumpers.
  EXPECT_GT((along_head.trail().back() - along_head.position_estimate()).norm(), 28.0);
  EXPECT_NEAR(along_head.gap_m(), 15.0 - 2.35 - 2.35, 0.05);
  EXPECT_NEAR(along_head.gap_m(), along_leader.gap_m(), 0.05);
  EXPECT_NEAR(along_head.trail_features().gap_m, along_head.gap_m(), 0.05);
  EXPECT_NEAR(along_head.trail_features().leader_left_m, 0.5, 0.05);

  // A checkpoint half-way: the follower restored from it goes on exactly as the original.
  ConvoyFollower original(head, veh, kConverter), restored(head, veh, kConverter);
  run(original, events, 1e9, 0, 500);
  core::StateWriter w;
  original.save_state(w);
  core::StateReader r(w.bytes(), "test");
  restored.load_state(r);
  const auto a = run(original, events, 1e9, 501, 1000);
  const auto b = run(restored, events, 1e9, 501, 1000);
  EXPECT_EQ(a.steering, b.steering);
  EXPECT_EQ(a.throttle, b.throttle);
  EXPECT_EQ(original.gap_m(), restored.gap_m());

  // The head falls silent at 5 s: lost after leader_lost_after_s, naming the head.
  ConvoyFollower silent(head, veh, kConverter);
  events.clear();
  const auto stop = run(silent, events, 5.0, 0, 1000);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, "leader_lost");
  EXPECT_NE(events[0].detail.find("h1"), std::string::npos) << events[0].detail;
  EXPECT_EQ(stop.braking, 1.0);
}
