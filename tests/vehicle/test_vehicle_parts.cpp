// Parts of the full vehicle on their own: tire model, powertrain, Ackermann steering, and the
// vehicle files.
#include <gtest/gtest.h>

#include <fstream>

#include "core/error.hpp"
#include "vehicle/powertrain.hpp"
#include "vehicle/steering.hpp"
#include "vehicle/tire_model.hpp"
#include "vehicle_test_util.hpp"

using namespace syndds;
using namespace syndds::vehicle;
using namespace syndds::vehicle::testing;

namespace {
/// Steady state of the tire under constant kinematics.
TireForce steady(const TireModel& tire, const TireKinematics& k) {
  TireState s;
  TireForce f;
  for (int i = 0; i < 20000; ++i) f = tire.update(k, 0.002, s);
  return f;
}
/// Brush-model magnitude for a linear force f_lin and a friction limit f_max.
double brush(double f_lin, double f_max) {
  const double psi = std::abs(f_lin) / f_max;
  const double m = psi >= 3 ? f_max : f_max * (psi - psi * psi / 3 + psi * psi * psi / 27);
  return f_lin < 0 ? -m : m;
}
}  // namespace

// Steady slip: kappa = (omega r - v) / v and tan(alpha) = v_y / v; small slip gives
// Fx = C_kappa kappa, Fy = -C_alpha tan(alpha) (slopes at the origin); larger slip follows the
// brush curve mu Fz (psi - psi^2/3 + psi^3/27), psi = C s / (mu Fz).
TEST(TireModel, SteadySlipFollowsTheBrushCurve) {
  const auto p = load("hmmwv");
  const TireModel tire(p.tire, p.wheels);
  TireKinematics k;
  k.normal_force_n = p.tire.nominal_load_n;
  k.ground_speed_mps = 10.0;
  k.friction = 0.8;
  const double f_max = 0.8 * p.tire.nominal_load_n;
  k.slip_velocity_x_mps = -1e-4;  // kappa = 1e-5
  auto f = steady(tire, k);
  EXPECT_NEAR(f.slip_ratio, 1e-5, 1e-12);
  EXPECT_NEAR(f.fx_n, p.tire.longitudinal_stiffness * 1e-5, 1e-3 * p.tire.longitudinal_stiffness * 1e-5);
  for (double kappa : {0.002, 0.01, 0.03, -0.02}) {
    k.slip_velocity_x_mps = -kappa * k.ground_speed_mps;
    f = steady(tire, k);
    EXPECT_NEAR(f.fx_n, brush(p.tire.longitudinal_stiffness * kappa, f_max), 1e-6 * f_max);
  }
  k.slip_velocity_x_mps = 0.0;
  k.slip_velocity_y_mps = 1e-4;  // tan(alpha) = 1e-5
  f = steady(tire, k);
  EXPECT_NEAR(f.fy_n, -p.tire.cornering_stiffness * 1e-5, 1e-3 * p.tire.cornering_stiffness * 1e-5);
  for (double tan_alpha : {0.01, 0.05, -0.03}) {
    k.slip_velocity_y_mps = tan_alpha * k.ground_speed_mps;
    f = steady(tire, k);
    EXPECT_NEAR(f.fy_n, brush(-p.tire.cornering_stiffness * tan_alpha, f_max), 1e-6 * f_max);
  }
  // Load dependence: (Fz / Fz0)^e.
  EXPECT_NEAR(tire.cornering_stiffness(0.5 * p.tire.nominal_load_n),
              p.tire.cornering_stiffness * std::pow(0.5, p.tire.stiffness_load_exponent), 1e-6);
}

// Large and combined slip saturate at mu Fz; a locked wheel slides at exactly mu Fz.
TEST(TireModel, CombinedSlipSaturatesAtFriction) {
  const auto p = load("hmmwv");
  const TireModel tire(p.tire, p.wheels);
  TireKinematics k;
  k.normal_force_n = 5000.0;
  k.ground_speed_mps = 10.0;
  k.friction = 0.7;
  k.slip_velocity_x_mps = 10.0;  // locked
  auto f = steady(tire, k);
  EXPECT_NEAR(f.fx_n, -0.7 * 5000.0, 1e-6);
  EXPECT_TRUE(f.sliding);
  for (double sx : {-0.5, -0.1, 0.05, 0.3}) {
    for (double sy : {-1.0, 0.2, 0.8}) {
      k.slip_velocity_x_mps = sx;
      k.slip_velocity_y_mps = sy;
      f = steady(tire, k);
      EXPECT_LE(std::hypot(f.fx_n, f.fy_n), 0.7 * 5000.0 * (1 + 1e-12));
      EXPECT_LT(f.fx_n * sx, 0.0);  // opposes the slip
      EXPECT_LT(f.fy_n * sy, 0.0);
    }
  }
}

// At standstill the tread is a spring: a displacement gives a restoring force, no drift.
TEST(TireModel, HoldsAtStandstill) {
  const auto p = load("hmmwv");
  const TireModel tire(p.tire, p.wheels);
  TireState s;
  TireKinematics k;
  k.normal_force_n = 6000.0;
  k.friction = 0.8;
  k.slip_velocity_x_mps = 0.01;  // 1 mm in 0.1 s
  for (int i = 0; i < 50; ++i) tire.update(k, 0.002, s);
  k.slip_velocity_x_mps = 0.0;
  const auto f = tire.update(k, 0.002, s);
  EXPECT_NEAR(s.deflection_x_m, -0.001, 1e-12);
  EXPECT_NEAR(f.fx_n,
              brush(tire.longitudinal_stiffness(6000.0) * -0.001 / p.tire.relaxation_length_m,
                    0.8 * 6000.0),
              1e-6);
  k.normal_force_n = 0.0;  // lifted: the tread relaxes
  EXPECT_EQ(tire.update(k, 0.002, s).fx_n, 0.0);
  EXPECT_EQ(s.deflection_x_m, 0.0);
}

TEST(Powertrain, ShiftsAtTheConfiguredSpeeds) {
  const auto p = load("hmmwv");
  Powertrain pt(p);
  EXPECT_EQ(pt.gear(), 0);
  pt.step(0.0, 0.0, 0.0, 0.002);
  EXPECT_EQ(pt.gear(), 0);
  pt.step(0.5, 0.0, 0.0, 0.002);
  EXPECT_EQ(pt.gear(), 1);
  EXPECT_GT(pt.step(0.5, 0.0, 0.0, 0.002), 0.0);  // launch torque at the wheels
  // Turbine speed just above the upshift speed in first gear, after the shift latency.
  const double to_rad = 2 * std::numbers::pi / 60;
  const double ratio1 = p.transmission.forward_ratios[0] * p.driveline.final_drive_ratio;
  for (int i = 0; i < 600; ++i) pt.step(0.5, 1.01 * p.transmission.upshift_rpm * to_rad * ratio1, 5.0, 0.002);
  EXPECT_EQ(pt.gear(), 2);
  const double ratio2 = p.transmission.forward_ratios[1] * p.driveline.final_drive_ratio;
  for (int i = 0; i < 600; ++i) pt.step(0.5, 0.99 * p.transmission.downshift_rpm * to_rad * ratio2, 5.0, 0.002);
  EXPECT_EQ(pt.gear(), 1);
  // Stopped with the throttle closed: neutral.
  pt.step(0.0, 0.0, 0.0, 0.002);
  EXPECT_EQ(pt.gear(), 0);
  // Engaging while rolling picks the gear that fits the speed: here third gear.
  const double ratio3 = p.transmission.forward_ratios[2] * p.driveline.final_drive_ratio;
  pt.step(0.5, 0.9 * p.transmission.upshift_rpm * to_rad * ratio3, 15.0, 0.002);
  EXPECT_EQ(pt.gear(), 3);
  pt.step(0.0, 0.0, 0.0, 0.002);
  EXPECT_EQ(pt.gear(), 0);
  // Idle governor holds the engine near idle in neutral.
  for (int i = 0; i < 5000; ++i) pt.step(0.0, 0.0, 0.0, 0.002);
  EXPECT_NEAR(pt.engine_rpm(), p.engine.idle_rpm, 0.05 * p.engine.idle_rpm);
}

// Ackermann: both front wheels' axes meet the rear-axle line at the same turn centre.
TEST(Steering, AckermannWheelsShareTheTurnCentre) {
  const auto p = load("hmmwv");
  for (double s : {-1.0, -0.3, 0.2, 1.0}) {
    const auto a = ackermann_angles(p, s);
    const double r = rear_axle_turn_radius_m(p, s);  // signed, left positive
    const double l = p.wheelbase_m(), t2 = p.front.half_track_m;
    EXPECT_NEAR(std::tan(a.left_rad) * (r - t2), l, 1e-9);
    EXPECT_NEAR(std::tan(a.right_rad) * (r + t2), l, 1e-9);
    const double inner = s > 0 ? a.left_rad : -a.right_rad;
    EXPECT_NEAR(inner, std::abs(s) * deg_to_rad(p.steering.max_angle_deg), 1e-12);
    EXPECT_NEAR(steering_for_rear_axle_radius(p, r), s, 1e-12);
  }
  EXPECT_THROW(steering_for_rear_axle_radius(p, 3.0), std::invalid_argument);
}

TEST(VehicleFiles, ShippedFilesLoadAndAreConsistent) {
  for (const std::string name : {"hmmwv", "utility"}) {
    const auto p = load(name);
    EXPECT_EQ(p.name, name);
    EXPECT_GT(p.wheelbase_m(), 1.0);
    EXPECT_GT(p.engine_peak_torque().first, 0.0);
    EXPECT_NEAR(p.static_wheel_load_n(true) * 2 + p.static_wheel_load_n(false) * 2,
                p.total_mass_kg() * kGravity, 1e-6);
  }
  const auto h = load("hmmwv");
  EXPECT_NEAR(h.total_mass_kg(), 2600.0, 50.0);  // docs/sources.md: whole vehicle about 2.6 t
  EXPECT_NEAR(h.wheelbase_m(), 3.378, 1e-9);
  EXPECT_NEAR(h.track_m(), 1.819, 1e-9);
}

TEST(VehicleFiles, NewKeysAreStrict) {
  const std::string file = std::string(SYNDDS_TEST_CONFIG_DIR) + "/vehicles/hmmwv.yaml";
  std::ifstream in(file);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto error_of = [](const std::string& t) {
    try {
      parse_vehicle_params(YamlNode::load_string(t, "v.yaml"));
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string bad = text;
  bad.replace(bad.find("relaxation_length_m: 0.25"), 25, "relaxation_lenght_m: 0.25");
  EXPECT_NE(error_of(bad).find("relaxation_lenght_m"), std::string::npos) << error_of(bad);
  bad = text;
  bad.replace(bad.find("steered: false"), 14, "steered: true");
  EXPECT_NE(error_of(bad).find("rear-axle steering is not supported"), std::string::npos);
  bad = text;
  bad.replace(bad.find("drag_area_m2: 2.4"), 17, "drag_area_m2: -1");
  EXPECT_NE(error_of(bad).find("chassis.drag_area_m2"), std::string::npos) << error_of(bad);
  // The earlier converter model's keys name their replacement.
  bad = text;
  bad.insert(bad.find("  converter_capacity_map:"), "  converter_stall_ratio: 2.0\n");
  EXPECT_NE(error_of(bad).find("replaced by converter_capacity_map"), std::string::npos)
      << error_of(bad);
  // Converter maps cover speed ratios 0 to 1.
  bad = text;
  bad.replace(bad.find("- [1.0, 35]"), 11, "- [0.95, 35]");
  EXPECT_NE(error_of(bad).find("speed ratios must run from 0 to 1"), std::string::npos)
      << error_of(bad);
}
