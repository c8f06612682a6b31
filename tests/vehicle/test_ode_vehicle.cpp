// Full ODE vehicle against the closed-form oracles of docs/sources.md.
// Measured numbers are printed with a "[measured]" tag (docs/vehicle-dynamics.md quotes them).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <set>

#include "vehicle/ode_vehicle.hpp"
#include "vehicle/steering.hpp"
#include "vehicle_test_util.hpp"

using namespace syndds;
using namespace syndds::vehicle;
using namespace syndds::vehicle::testing;

namespace {

/// Static axle load shares from the lever rule: (front, rear) = m g (b, a) / L.
std::pair<double, double> lever_rule_axle_loads(const VehicleParams& p) {
  const double m = p.chassis.mass_kg + 4 * p.wheels.mass_kg;
  const double x_com =
      (p.chassis.mass_kg * p.chassis.com_m.x() + 2 * p.wheels.mass_kg * (p.front.x_m + p.rear.x_m)) /
      m;
  const double l = p.front.x_m - p.rear.x_m;
  const double a = p.front.x_m - x_com, b = x_com - p.rear.x_m;
  return {m * kGravity * b / l, m * kGravity * a / l};
}

/// Radius of the path of a point fixed in the chassis (vehicle-frame offset), from v / yaw rate.
double path_radius(const VehicleSnapshot& s, const Vec3& offset) {
  const Vec3 arm = s.pose.orientation * offset;
  const Vec3 v = s.linear_velocity + s.angular_velocity.cross(arm);
  return std::hypot(v.x(), v.y()) / std::abs(s.angular_velocity.z());
}

class StaticLoads : public ::testing::TestWithParam<std::string> {};

}  // namespace

// Wf = m g b / L, Wr = m g a / L at rest on level ground, within 2 %.
TEST_P(StaticLoads, AxleLoadsFollowTheLeverRule) {
  const auto p = load(GetParam());
  OdeVehicleModel m(p, Pose{}, flat());
  const auto s = m.snapshot();
  const auto [wf, wr] = lever_rule_axle_loads(p);
  const double front = s.wheels[0].vertical_load_n + s.wheels[1].vertical_load_n;
  const double rear = s.wheels[2].vertical_load_n + s.wheels[3].vertical_load_n;
  std::printf("[measured] %s axle loads front %.1f N (oracle %.1f), rear %.1f N (oracle %.1f)\n",
              GetParam().c_str(), front, wf, rear, wr);
  EXPECT_NEAR(front, wf, 0.02 * wf);
  EXPECT_NEAR(rear, wr, 0.02 * wr);
  EXPECT_NEAR(s.wheels[0].vertical_load_n, s.wheels[1].vertical_load_n, 1e-3 * wf);
}

// Spring without preload: deflection at rest = sprung corner load / spring rate, within 2 %.
// With the default preload (static share) the vehicle rests at design height.
TEST_P(StaticLoads, SuspensionDeflectionAtRest) {
  auto p = load(GetParam());
  const auto [wf, wr] = lever_rule_axle_loads(p);
  const double sprung_f = wf / 2 - p.wheels.mass_kg * kGravity;
  const double sprung_r = wr / 2 - p.wheels.mass_kg * kGravity;
  const double expected_f = sprung_f / p.front.spring_rate_npm;
  const double expected_r = sprung_r / p.rear.spring_rate_npm;
  {
    OdeVehicleModel m(p, Pose{}, flat());
    const auto d = m.wheel_diagnostics();
    for (int i = 0; i < 4; ++i) {
      EXPECT_LT(std::abs(d[i].suspension_compression_m), 0.02 * (i < 2 ? expected_f : expected_r));
    }
  }
  p.front.preload_n = 0.0;
  p.rear.preload_n = 0.0;
  OdeVehicleModel m(p, Pose{}, flat());
  const auto d = m.wheel_diagnostics();
  std::printf("[measured] %s spring deflection without preload front %.4f m (oracle %.4f), "
              "rear %.4f m (oracle %.4f)\n",
              GetParam().c_str(), d[0].suspension_compression_m, expected_f,
              d[2].suspension_compression_m, expected_r);
  for (int i = 0; i < 2; ++i) EXPECT_NEAR(d[i].suspension_compression_m, expected_f, 0.02 * expected_f);
  for (int i = 2; i < 4; ++i) EXPECT_NEAR(d[i].suspension_compression_m, expected_r, 0.02 * expected_r);
}

INSTANTIATE_TEST_SUITE_P(Vehicles, StaticLoads, ::testing::Values("hmmwv", "utility"));

// Steady low-speed turn: R = L / tan(delta) at the rear-axle centre; delta 10 deg: 19.16 m.
TEST(OdeVehicle, LowSpeedTurningRadiusMatchesGeometry) {
  const auto p = load("hmmwv");
  const double delta = deg_to_rad(10.0);
  const double oracle = p.wheelbase_m() / std::tan(delta);
  EXPECT_NEAR(oracle, 19.16, 0.01);
  const double steering = steering_for_rear_axle_radius(p, oracle);
  OdeVehicleModel m(p, Pose{}, flat());
  drive(m, 25.0, 2.0, steering);
  double sum = 0.0;
  int n = 0;
  for (int k = 0; k < 50; ++k) {
    drive(m, 0.1, 2.0, steering);
    sum += path_radius(m.snapshot(), Vec3(p.rear.x_m, 0, 0));
    ++n;
  }
  const double r = sum / n;
  std::printf("[measured] turning radius at 2 m/s, bicycle angle 10 deg: %.3f m (oracle %.3f)\n",
              r, oracle);
  EXPECT_NEAR(r, oracle, 0.05 * oracle);
}

// Full lock at low speed. Chrono's published minimum turning radius 7.62 m is defined by
// max steer = asin(L / (R - t/2)), i.e. R = L / sin(inner) + t/2 (front-axle-centre path).
TEST(OdeVehicle, MinimumTurningRadiusNearPublished) {
  const auto p = load("hmmwv");
  const double inner = deg_to_rad(p.steering.max_angle_deg);
  const double rear_oracle = p.wheelbase_m() / std::tan(inner) + p.front.half_track_m;
  OdeVehicleModel m(p, Pose{}, flat());
  drive(m, 20.0, 1.5, 1.0);
  const auto s = m.snapshot();
  const double r_rear = path_radius(s, Vec3(p.rear.x_m, 0, 0));
  const double r_front = path_radius(s, Vec3(p.front.x_m, 0, 0));
  const double r_outer = path_radius(s, Vec3(p.front.x_m, -p.front.half_track_m, 0));
  std::printf("[measured] full lock at 1.5 m/s: rear-axle centre %.3f m (geometry %.3f), "
              "front-axle centre %.3f m (published 7.62), outer front wheel %.3f m\n",
              r_rear, rear_oracle, r_front, r_outer);
  EXPECT_NEAR(r_rear, rear_oracle, 0.05 * rear_oracle);
  EXPECT_NEAR(r_front, 7.62, 0.05 * 7.62);
}

// Locked-wheel stop from 20 m/s on mu 0.8: d = v^2 / (2 mu g) = 25.5 m, within 10 %.
TEST(OdeVehicle, BrakingDistanceFollowsFrictionLimit) {
  const auto p = load("hmmwv");
  const double mu = 0.8, v0 = 20.0;
  OdeVehicleModel m(p, Pose{}, flat(mu));
  m.set_speed(v0);
  const Vec3 x0 = m.snapshot().pose.position;
  m.set_inputs({0.0, 0.0, 1.0});
  double t = 0.0;
  while (forward_speed(m.snapshot()) > 0.01 && t < 20.0) {
    m.advance(0.002);
    t += 0.002;
  }
  const double d = (m.snapshot().pose.position - x0).head<2>().norm();
  const double oracle = v0 * v0 / (2 * mu * kGravity);
  std::printf("[measured] braking from %.0f m/s: %.2f m in %.2f s (oracle %.2f m)\n", v0, d, t,
              oracle);
  EXPECT_NEAR(d, oracle, 0.1 * oracle);
}

// Full throttle from rest: every gear in order, then a top speed plausible for the class.
TEST(OdeVehicle, FullThrottleShiftsThroughEveryGear) {
  for (const std::string name : {"hmmwv", "utility"}) {
    const auto p = load(name);
    OdeVehicleModel m(p, Pose{}, flat());
    m.set_inputs({0.0, 1.0, 0.0});
    std::vector<int> gears;
    double t_100 = -1.0;  // time to 60 km/h
    for (int k = 0; k < 9000; ++k) {  // 90 s
      run(m, 0.01);
      const auto s = m.snapshot();
      if (gears.empty() || gears.back() != s.gear) gears.push_back(s.gear);
      if (t_100 < 0 && forward_speed(s) > 60 / 3.6) t_100 = s.time_s;
    }
    const auto s0 = m.snapshot();
    run(m, 1.0);
    const auto s1 = m.snapshot();
    const double v_top = forward_speed(s1);
    std::string seq;
    for (int g : gears) seq += std::to_string(g) + " ";
    std::printf("[measured] %s full throttle: gears %s; 0-60 km/h %.1f s; top speed %.2f m/s "
                "(%.0f km/h) at %.0f rpm\n",
                name.c_str(), seq.c_str(), t_100, v_top, v_top * 3.6, s1.engine_speed_rpm);
    std::vector<int> expected;
    for (int g = 1; g <= static_cast<int>(p.transmission.forward_ratios.size()); ++g) {
      expected.push_back(g);
    }
    EXPECT_EQ(gears, expected);
    EXPECT_GT(v_top, 15.0);  // light utility / HMMWV class: 55-110 km/h
    EXPECT_LT(v_top, 31.0);
    EXPECT_LT(std::abs(forward_speed(s1) - forward_speed(s0)), 0.05);  // settled at top speed
  }
}

// Ten minutes of slalom at 10 m/s: finite, bounded, still upright and moving.
TEST(OdeVehicle, TenMinutesOfDrivingStayBounded) {
  const auto p = load("hmmwv");
  OdeVehicleModel m(p, Pose{}, flat());
  double max_tilt = 0.0, max_speed = 0.0, path = 0.0;
  Vec3 last = m.snapshot().pose.position;
  for (int k = 0; k < 60000; ++k) {  // 600 s in 10 ms frames
    const auto s = m.snapshot();
    const double steering = 0.3 * std::sin(2 * std::numbers::pi * s.time_s / 8.0);
    m.set_inputs(hold_speed(s, 10.0, steering));
    run(m, 0.01);
    const auto n = m.snapshot();
    ASSERT_TRUE(n.pose.position.allFinite() && n.linear_velocity.allFinite() &&
                n.angular_velocity.allFinite())
        << "at t = " << n.time_s;
    const Vec3 up = n.pose.orientation * Vec3::UnitZ();
    max_tilt = std::max(max_tilt, std::acos(std::min(1.0, up.z())));
    max_speed = std::max(max_speed, n.speed_mps());
    ASSERT_LT(std::abs(n.pose.position.z() - 0.45), 0.2) << "at t = " << n.time_s;
    path += (n.pose.position - last).norm();
    last = n.pose.position;
  }
  std::printf("[measured] 600 s slalom: path %.0f m, max tilt %.2f deg, max speed %.2f m/s\n",
              path, rad_to_deg(max_tilt), max_speed);
  EXPECT_GT(path, 5500.0);
  EXPECT_LT(rad_to_deg(max_tilt), 15.0);
  EXPECT_LT(max_speed, 13.0);
}

// No creep: a vehicle left alone for 60 s moves less than 1 cm, on level ground without
// brakes and on an 8 % slope with the brakes on.
TEST(OdeVehicle, RestingVehicleDoesNotCreep) {
  const auto p = load("hmmwv");
  {
    OdeVehicleModel m(p, Pose{}, flat());
    const Vec3 x0 = m.snapshot().pose.position;
    run(m, 60.0);
    const double drift = (m.snapshot().pose.position - x0).norm();
    std::printf("[measured] level ground, 60 s at rest: drift %.2e m\n", drift);
    EXPECT_LT(drift, 0.01);
  }
  {
    Pose start;
    start.orientation = quat_from_yaw(0.3);
    OdeVehicleModel m(p, start, ramp(0.08));
    m.set_inputs({0.0, 0.0, 1.0});
    const auto s0 = m.snapshot();
    run(m, 60.0);
    const auto s1 = m.snapshot();
    const double drift = (s1.pose.position - s0.pose.position).norm();
    std::printf("[measured] 8 %% slope, brakes on, 60 s: drift %.2e m\n", drift);
    EXPECT_LT(drift, 0.01);
  }
}

// The vehicle sits on a height map: chassis pitched with the slope, wheels loaded.
TEST(OdeVehicle, SettlesOnHeightmapSlope) {
  const auto p = load("hmmwv");
  const double slope = 0.1;
  Pose start;
  start.position = Vec3(5.0, -3.0, 100.0);  // z is ignored
  OdeVehicleModel m(p, start, ramp(slope));
  m.set_inputs({0.0, 0.0, 1.0});
  run(m, 1.0);
  const auto s = m.snapshot();
  const Vec3 fwd = s.pose.orientation * Vec3::UnitX();
  const double pitch = std::atan2(fwd.z(), std::hypot(fwd.x(), fwd.y()));
  EXPECT_NEAR(pitch, std::atan(slope), deg_to_rad(0.5));
  EXPECT_NEAR(s.pose.position.x(), 5.0, 0.02);
  EXPECT_NEAR(s.pose.position.y(), -3.0, 0.02);
  const double ground = slope * 5.0;
  EXPECT_NEAR(s.pose.position.z() - ground, p.wheels.radius_m, 0.1);
  double total = 0.0;
  for (const auto& w : s.wheels) {
    EXPECT_GT(w.vertical_load_n, 1000.0);
    total += w.vertical_load_n;
  }
  // Normal loads carry m g cos(theta).
  const double m_total = p.total_mass_kg();
  EXPECT_NEAR(total, m_total * kGravity * std::cos(std::atan(slope)), 0.02 * m_total * kGravity);
}

// Driving into obstacles stops the vehicle and records exactly one collision per obstacle.
TEST(OdeVehicle, ObstacleStopsVehicleAndIsReportedOnce) {
  const auto p = load("hmmwv");
  struct Case {
    world::ShapeKind shape;
    Vec3 size;
    double centre_z;
  };
  const Case cases[] = {{world::ShapeKind::box, Vec3(0.5, 4.0, 1.0), 1.0},
                        {world::ShapeKind::cylinder, Vec3(0.4, 0.0, 2.0), 2.0},
                        {world::ShapeKind::sphere, Vec3(1.2, 0.0, 0.0), 0.9}};
  for (const auto& c : cases) {
    world::Obstacle wall;
    wall.id = "obstacle";
    wall.shape = c.shape;
    wall.size = c.size;
    wall.pose.position = Vec3(25.0, 0.0, c.centre_z);
    world::Obstacle far_away = wall;
    far_away.id = "elsewhere";
    far_away.pose.position = Vec3(25.0, 40.0, c.centre_z);
    OdeVehicleModel m(p, Pose{}, flat(), {far_away, wall});
    std::vector<CollisionContact> events;
    double speed_at_hit = 0.0;
    for (int k = 0; k < 2000; ++k) {  // 20 s: reach ~8 m/s, hit, keep pushing
      const auto s = m.snapshot();
      m.set_inputs(hold_speed(s, 8.0, 0.0));
      run(m, 0.01);
      auto got = m.take_collisions();
      if (!got.empty() && events.empty()) speed_at_hit = forward_speed(s);
      events.insert(events.end(), got.begin(), got.end());
    }
    const auto s = m.snapshot();
    const double front = s.pose.position.x() + p.chassis.box_centre_m.x() +
                         p.chassis.half_extents_m.x();
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(events[0].obstacle_id, "obstacle");
    const double mass = p.total_mass_kg();
    std::printf("[measured] %s hit at %.2f m/s: impulse %.0f N s (m v = %.0f), contact x %.2f, "
                "vehicle front at x %.2f, speed after %.3f m/s\n",
                c.shape == world::ShapeKind::box ? "box" :
                c.shape == world::ShapeKind::cylinder ? "cylinder" : "sphere",
                speed_at_hit, events[0].impulse_ns, mass * speed_at_hit,
                events[0].position.x(), front, forward_speed(s));
    EXPECT_GT(events[0].impulse_ns, 0.0);
    EXPECT_LT(events[0].impulse_ns, 1.5 * mass * speed_at_hit);
    EXPECT_LT(std::abs(forward_speed(s)), 0.3);        // stopped (wheels may still push)
    EXPECT_LT(front, 25.0 + 0.05);                      // and not through the obstacle
    EXPECT_GT(speed_at_hit, 5.0);
  }
}

// Two runs give bit-identical trajectories; so do interleaved instances in one process.
TEST(OdeVehicle, DeterministicBitForBit) {
  const auto p = load("hmmwv");
  world::Obstacle rock;
  rock.id = "rock";
  rock.shape = world::ShapeKind::sphere;
  rock.size = Vec3(1.0, 0, 0);
  rock.pose.position = Vec3(30.0, 6.0, 0.5);
  auto record = [](const VehicleSnapshot& s, std::vector<double>& out) {
    auto push = [&](const Vec3& v) { out.insert(out.end(), v.data(), v.data() + 3); };
    push(s.pose.position);
    out.insert(out.end(), s.pose.orientation.coeffs().data(),
               s.pose.orientation.coeffs().data() + 4);
    push(s.linear_velocity);
    push(s.angular_velocity);
    push(s.linear_acceleration);
    for (const auto& w : s.wheels) {
      push(w.pose.position);
      out.push_back(w.spin_rad_s);
      out.push_back(w.vertical_load_n);
    }
    out.push_back(s.engine_speed_rpm);
    out.push_back(s.gear);
  };
  auto script = [](double t) {
    return DriverInputs{0.4 * std::sin(t), t < 6 ? 0.7 : 0.2, t > 8 ? 0.3 : 0.0};
  };
  const world::Obstacles obstacles{rock};
  auto run_alone = [&] {
    std::vector<double> out;
    OdeVehicleModel m(p, Pose{}, flat(), obstacles);
    for (int k = 0; k < 1000; ++k) {
      m.set_inputs(script(k * 0.01));
      run(m, 0.01);
      record(m.snapshot(), out);
    }
    return out;
  };
  const auto a = run_alone();
  const auto b = run_alone();
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(double)));

  // Two instances stepped alternately, plus a third with other inputs in between.
  std::vector<double> c, d;
  OdeVehicleModel mc(p, Pose{}, flat(), obstacles);
  OdeVehicleModel other(p, Pose{}, flat(), obstacles);
  OdeVehicleModel md(p, Pose{}, flat(), obstacles);
  for (int k = 0; k < 1000; ++k) {
    mc.set_inputs(script(k * 0.01));
    md.set_inputs(script(k * 0.01));
    other.set_inputs({-0.5, 1.0, 0.0});
    for (int i = 0; i < 5; ++i) {
      mc.advance(0.002);
      other.advance(0.002);
      md.advance(0.002);
    }
    record(mc.snapshot(), c);
    record(md.snapshot(), d);
  }
  ASSERT_EQ(a.size(), c.size());
  EXPECT_EQ(0, std::memcmp(a.data(), c.data(), a.size() * sizeof(double)));
  EXPECT_EQ(0, std::memcmp(a.data(), d.data(), a.size() * sizeof(double)));
}

// Snapshot basics: reference frame at wheel-centre height between the axles, acceleration
// from the last step, inputs as applied, steering rate limit.
TEST(OdeVehicle, SnapshotDescribesTheVehicle) {
  auto p = load("hmmwv");
  p.steering.rate_deg_s = 60.0;
  Pose start;
  start.position = Vec3(3.0, 4.0, 0.0);
  start.orientation = quat_from_yaw(1.0);
  OdeVehicleModel m(p, start, flat());
  auto s = m.snapshot();
  EXPECT_EQ(s.time_s, 0.0);
  EXPECT_NEAR(s.pose.position.x(), 3.0, 1e-3);
  EXPECT_NEAR(s.pose.position.y(), 4.0, 1e-3);
  EXPECT_NEAR(yaw_of(s.pose.orientation), 1.0, 1e-4);
  EXPECT_LT(s.linear_velocity.norm(), 1e-9);
  EXPECT_EQ(s.gear, 0);
  ASSERT_EQ(s.wheels.size(), 4u);
  const Vec3 mid_front = 0.5 * (s.wheels[0].pose.position + s.wheels[1].pose.position);
  const Vec3 mid_rear = 0.5 * (s.wheels[2].pose.position + s.wheels[3].pose.position);
  EXPECT_LT((0.5 * (mid_front + mid_rear) - s.pose.position).norm(), 0.01);
  EXPECT_NEAR((mid_front - mid_rear).norm(), p.wheelbase_m(), 0.01);
  // Steering at 60 deg/s with a 30.23 deg range: half a second to reach full lock.
  m.set_inputs({1.0, 0.0, 0.0});
  run(m, 0.25);
  s = m.snapshot();
  EXPECT_NEAR(s.inputs.steering, 0.25 * 60.0 / p.steering.max_angle_deg, 1e-9);
  run(m, 0.5);
  s = m.snapshot();
  EXPECT_DOUBLE_EQ(s.inputs.steering, 1.0);
  const auto angles = ackermann_angles(p, 1.0);
  EXPECT_NEAR(s.wheels[0].steer_angle_rad, angles.left_rad, 1e-3);
  EXPECT_NEAR(s.wheels[1].steer_angle_rad, angles.right_rad, 1e-3);
  EXPECT_NEAR(s.wheels[0].steer_angle_rad, deg_to_rad(p.steering.max_angle_deg), 1e-3);
  // Acceleration is the finite difference over the last step.
  m.set_inputs({0.0, 1.0, 0.0});
  run(m, 2.0);
  const auto before = m.snapshot();
  m.advance(0.002);
  const auto after = m.snapshot();
  const Vec3 fd = (after.linear_velocity - before.linear_velocity) / 0.002;
  EXPECT_LT((after.linear_acceleration - fd).norm(), 1e-9);
  EXPECT_GT(after.gear, 0);
  EXPECT_GT(after.engine_speed_rpm, p.engine.idle_rpm);
  EXPECT_THROW(m.advance(0.0), std::invalid_argument);
  EXPECT_THROW(m.set_inputs({std::nan(""), 0.0, 0.0}), std::invalid_argument);
}

// Rolling over a rock with the front and then the rear wheel is one episode; each rock counts.
TEST(OdeVehicle, RollingOverRocksCountsEachRockOnce) {
  const auto p = load("hmmwv");
  world::Obstacles rocks;
  for (int k = 0; k < 2; ++k) {
    world::Obstacle r;
    r.id = "rock" + std::to_string(k);
    r.label = "rock";
    r.shape = world::ShapeKind::sphere;
    r.size = Vec3(0.3, 0, 0);
    r.pose.position = Vec3(15.0 + 12.0 * k, k == 0 ? p.front.half_track_m : -p.front.half_track_m,
                           0.0);
    rocks.push_back(r);
  }
  OdeVehicleModel m(p, Pose{}, flat(), rocks);
  std::vector<std::string> hits;
  for (int k = 0; k < 800; ++k) {
    // Hold the line y = 0 (the first rock pushes the vehicle sideways by up to half a metre).
    const auto now = m.snapshot();
    const double steering =
        std::clamp(-0.5 * now.pose.position.y() - 2.0 * yaw_of(now.pose.orientation), -0.3, 0.3);
    drive(m, 0.01, 6.0, steering);
    for (const auto& c : m.take_collisions()) hits.push_back(c.obstacle_id);
  }
  const auto s = m.snapshot();
  EXPECT_EQ(hits, (std::vector<std::string>{"rock0", "rock1"}));
  EXPECT_GT(s.pose.position.x(), 35.0);  // climbed over both
  EXPECT_LT(std::abs(s.pose.position.y()), 1.0);  // deflected a little, steered back
}
