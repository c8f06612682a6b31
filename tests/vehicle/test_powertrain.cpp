// The HMMWV powertrain against numbers computed by hand from the published maps (Project
// Chrono's public HMMWV data: HMMWV_EngineShafts, HMMWV_AutomaticTransmissionShafts): the
// converter's maps, the full-throttle stall point, the launch acceleration with the throttle
// just open and wide open, the idle creep speed and the speed at each upshift.
//
// The oracles below use the published numbers typed here, not the vehicle file, and simple
// closed forms (quasi-static engine, rigid wheels rolling at the effective radius); what they
// neglect is named next to each tolerance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <utility>
#include <vector>

#include "vehicle/ode_vehicle.hpp"
#include "vehicle/powertrain.hpp"
#include "vehicle_test_util.hpp"

using namespace syndds;
using namespace syndds::vehicle;
using namespace syndds::vehicle::testing;

namespace {

constexpr double kRpm = 2.0 * std::numbers::pi / 60.0;  // rad/s per rpm
constexpr double kAirDensity = 1.2;
using Rows = std::vector<std::pair<double, double>>;

// Published converter maps over the speed ratio sr = w_turbine / w_pump.
const Rows kCapacity = {{0.0, 15}, {0.25, 15}, {0.5, 15}, {0.75, 16}, {0.9, 18}, {1.0, 35}};
const Rows kTorqueRatio = {{0.0, 2.0}, {0.25, 1.8}, {0.5, 1.5}, {0.75, 1.15}, {1.0, 1.0}};
// Published gearing and shift speeds.
constexpr double kGears[3] = {0.2, 0.4, 0.8};
constexpr double kFinalDrive = 0.2;
constexpr double kUpshiftRpm = 2500.0;

double lerp_rows(const Rows& rows, double x) {
  if (x <= rows.front().first) return rows.front().second;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    if (x <= rows[i].first) {
      const double t = (x - rows[i - 1].first) / (rows[i].first - rows[i - 1].first);
      return rows[i - 1].second + t * (rows[i].second - rows[i - 1].second);
    }
  }
  return rows.back().second;
}

/// Root of a function that changes sign once on [lo, hi].
double bisect(const std::function<double(double)>& f, double lo, double hi) {
  const bool rising = f(hi) > f(lo);
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    ((f(mid) > 0) == rising ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi);
}

/// Engine torque at w (rad/s) for a throttle, as docs/vehicle-dynamics.md states the model:
/// full-throttle map times s minus motoring drag times (1 - s), s = max(throttle, governor),
/// the governor adding up to 0.2 within 10 % below idle.
double engine_torque(const VehicleParams& p, double w, double throttle) {
  const double rpm = w / kRpm;
  const double idle = p.engine.idle_rpm;
  const double governor = 0.2 * std::clamp((idle - rpm) / (0.1 * idle), 0.0, 1.0);
  const double s = std::max(throttle, governor);
  return s * p.engine_torque_nm(rpm) -
         (1.0 - s) * p.engine.motoring_torque_nm * rpm / p.engine.max_rpm;
}

/// Quasi-static converter: the engine at the speed where its torque equals the pump torque
/// (w / K(sr))^2 for a turbine speed w_t. Returns {engine speed, pump torque, turbine torque}.
struct ConverterPoint {
  double w_engine, pump, turbine;
};
ConverterPoint converter_equilibrium(const VehicleParams& p, double w_turbine, double throttle) {
  auto pump = [&](double w) {
    const double k = lerp_rows(kCapacity, std::max(w_turbine / w, 0.0));
    return (w / k) * (w / k);
  };
  const double w = bisect([&](double x) { return engine_torque(p, x, throttle) - pump(x); },
                          std::max(w_turbine, 1.0) * 1.0001, 3000.0 * kRpm);
  const double sr = w_turbine / w;
  return {w, pump(w), lerp_rows(kTorqueRatio, sr) * pump(w)};
}

/// The vehicle's numbers the oracles need: mass, radii, rotating inertia in `gear`.
struct Body {
  double mass, r, r_eff, j_total, weight, deflection;
  /// Rolling resistance (its moment f Fz (r - deflection) at the wheel radius) and drag.
  double resistance(const VehicleParams& p, double v) const {
    return p.tire.rolling_resistance * weight * (r - deflection) / r +
           0.5 * kAirDensity * p.chassis.drag_area_m2 * v * v;
  }
};
Body body_of(const VehicleParams& p, int gear) {
  const double m = p.total_mass_kg();
  const double deflection = 0.25 * m * kGravity / p.tire.vertical_stiffness_npm;
  const double overall = kGears[gear - 1] * kFinalDrive;
  // Wheels + in-gear shaft (0.3 kg m2) + drive shaft (0.5 kg m2), published shaft inertias.
  const double j = 4.0 * p.wheels.spin_inertia_kgm2 + 0.3 / (overall * overall) +
                   0.5 / (kFinalDrive * kFinalDrive);
  return {m, p.wheels.radius_m, p.wheels.radius_m - deflection / 3.0, j, m * kGravity, deflection};
}

/// Drive force at the ground for the measured shaft speeds in `gear`: the turbine torque of the
/// maps (engine at w_engine, turbine at w_wheel / ratio) through the gears, at the loaded
/// radius (the tire's force acts at the ground, r - deflection under the wheel centre).
double drive_force(const VehicleParams& p, int gear, double w_wheel, double w_engine) {
  const Body b = body_of(p, gear);
  const double overall = kGears[gear - 1] * kFinalDrive;
  const double sr = w_wheel / overall / w_engine;
  const double k = lerp_rows(kCapacity, sr);
  const double turbine = lerp_rows(kTorqueRatio, sr) * (w_engine / k) * (w_engine / k);
  return turbine / overall / (b.r - b.deflection);
}

/// Runs from rest at a fixed throttle on flat ground and samples every 10 ms.
std::vector<VehicleSnapshot> launch(const VehicleParams& p, double throttle, double seconds,
                                    double friction) {
  OdeVehicleModel m(p, Pose{}, flat(friction));
  m.set_inputs({0.0, throttle, 0.0});
  std::vector<VehicleSnapshot> out{m.snapshot()};
  for (int k = 0; k < std::lround(seconds / 0.01); ++k) {
    run(m, 0.01);
    out.push_back(m.snapshot());
  }
  return out;
}

double mean_spin(const VehicleSnapshot& s) {
  double w = 0.0;
  for (const auto& wh : s.wheels) w += 0.25 * wh.spin_rad_s;
  return w;
}

/// Forward speed of the whole vehicle's centre of mass: the chassis COM (which swings fore
/// and aft as the chassis pitches on its springs) and the wheels (they move with the chassis
/// reference point: the hinges sit at its height). Its rate of change is the net external
/// force over the mass.
double com_speed(const VehicleParams& p, const VehicleSnapshot& s) {
  const Vec3 arm = s.pose.orientation * p.chassis.com_m;
  const Vec3 v_chassis = s.linear_velocity + s.angular_velocity.cross(arm);
  const Vec3 v = (p.chassis.mass_kg * v_chassis + 4.0 * p.wheels.mass_kg * s.linear_velocity) /
                 p.total_mass_kg();
  return v.dot(s.pose.orientation * Vec3::UnitX());
}

/// Launch in first gear between the samples where the vehicle passes v0 and v1: the measured
/// speed gain of the centre of mass and the gain the maps predict, the impulse of the drive
/// force at the measured engine and wheel speeds, less rolling resistance and drag, less what
/// spun up the wheels and shafts (J_total times their speed gain at the loaded radius).
struct SpeedGain {
  double measured = 0.0, predicted = 0.0;
};
SpeedGain first_gear_gain(const VehicleParams& p, const std::vector<VehicleSnapshot>& run_,
                          double v0, double v1) {
  std::size_t i0 = 0, i1 = 0;
  for (std::size_t i = 0; i < run_.size() && i1 == 0; ++i) {
    if (i0 == 0 && forward_speed(run_[i]) >= v0) i0 = i;
    if (i0 != 0 && forward_speed(run_[i]) >= v1) i1 = i;
  }
  if (i1 == 0) {
    ADD_FAILURE() << "never reached " << v1 << " m/s";
    return {};
  }
  const Body b = body_of(p, 1);
  double impulse = 0.0;
  for (std::size_t i = i0; i < i1; ++i) {
    EXPECT_EQ(run_[i].gear, 1) << "at t = " << run_[i].time_s;
    const double dt = run_[i + 1].time_s - run_[i].time_s;
    auto force = [&](const VehicleSnapshot& s) {
      return drive_force(p, 1, mean_spin(s), s.engine_speed_rpm * kRpm) -
             b.resistance(p, forward_speed(s));
    };
    impulse += 0.5 * (force(run_[i]) + force(run_[i + 1])) * dt;  // trapezoid
  }
  impulse -= b.j_total * (mean_spin(run_[i1]) - mean_spin(run_[i0])) / (b.r - b.deflection);
  return {com_speed(p, run_[i1]) - com_speed(p, run_[i0]), impulse / b.mass};
}

}  // namespace

TEST(Powertrain, VehicleFileCarriesThePublishedHmmwvPowertrain) {
  const auto p = load("hmmwv");
  EXPECT_EQ(p.transmission.converter_capacity_map, kCapacity);
  EXPECT_EQ(p.transmission.converter_torque_ratio_map, kTorqueRatio);
  EXPECT_EQ(p.transmission.forward_ratios, std::vector<double>(kGears, kGears + 3));
  EXPECT_EQ(p.driveline.final_drive_ratio, kFinalDrive);
  EXPECT_EQ(p.transmission.upshift_rpm, kUpshiftRpm);
  EXPECT_EQ(p.transmission.downshift_rpm, 1200.0);
  EXPECT_EQ(p.transmission.shift_time_s, 1.0);  // gear-shift latency
  EXPECT_EQ(p.engine.inertia_kgm2, 0.5);         // motor shaft
  EXPECT_EQ(p.transmission.ingear_shaft_inertia_kgm2, 0.3);
  EXPECT_EQ(p.driveline.driveshaft_inertia_kgm2, 0.5);
  // Reflected to the wheels in first gear: 0.3 / 0.04^2 + 0.5 / 0.2^2 = 200 kg m2.
  EXPECT_NEAR(p.driveline_inertia_at_wheels_kgm2(1), 200.0, 1e-9);
  EXPECT_NEAR(p.driveline_inertia_at_wheels_kgm2(0), 12.5, 1e-9);
}

TEST(Powertrain, ConverterTorquesFollowThePublishedMaps) {
  const auto p = load("hmmwv");
  const Powertrain pt(p);
  const double w = 1500.0 * kRpm;
  for (double sr : {0.0, 0.1, 0.3, 0.6, 0.8, 0.95, 0.985}) {
    const double k = lerp_rows(kCapacity, sr);
    const double pump = (w / k) * (w / k);
    const auto [tp, tt] = pt.converter_torques(w, sr * w);
    EXPECT_NEAR(tp, pump, 1e-9 * pump) << "sr " << sr;
    EXPECT_NEAR(tt, lerp_rows(kTorqueRatio, sr) * pump, 1e-9 * pump) << "sr " << sr;
  }
  // Worked value: stall at 1500 rpm takes (157.08 / 15)^2 = 109.7 N m and gives twice that.
  EXPECT_NEAR(pt.converter_torques(w, 0.0).first, 109.66, 0.01);
  EXPECT_NEAR(pt.converter_torques(w, 0.0).second, 219.3, 0.1);
  // Turbine backwards (vehicle rolling back in a forward gear): read as stall.
  EXPECT_NEAR(pt.converter_torques(w, -0.2 * w).second, 2.0 * (w / 15) * (w / 15), 1e-9);
  // Overrun (reverse flow): the turbine drives the engine with K(1 / sr), no multiplication.
  for (double sr : {1.5, 2.0, 4.0}) {
    const double k = lerp_rows(kCapacity, 1.0 / sr);
    const auto [tp, tt] = pt.converter_torques(w, sr * w);
    EXPECT_NEAR(tp, -(w / k) * (w / k), 1e-9 * (w / k) * (w / k)) << "sr " << sr;
    EXPECT_EQ(tt, tp);
  }
  // Through the coupling point the torques pass zero continuously (no chatter).
  EXPECT_NEAR(pt.converter_torques(w, w).first, 0.0, 0.01 * (w / 35) * (w / 35));
  double last = pt.converter_torques(w, 0.97 * w).second;
  for (double sr = 0.97; sr <= 1.03; sr += 0.0005) {
    const double t = pt.converter_torques(w, sr * w).second;
    EXPECT_LE(t, last + 1e-9) << "sr " << sr;               // falls monotonically
    EXPECT_LT(std::abs(t - last), 0.1 * (w / 35) * (w / 35)) << "sr " << sr;  // no jump
    last = t;
  }
}

// Full throttle, turbine held: the engine settles where its map torque equals (w / 15)^2.
TEST(Powertrain, FullThrottleStallMatchesTheMaps) {
  const auto p = load("hmmwv");
  Powertrain pt(p);
  for (int i = 0; i < 1500; ++i) pt.step(1.0, 0.0, 0.0, 0.002);  // 3 s, wheels held
  // Published map between 2500 rpm (558 N m) and 2700 rpm (-400 N m), linear.
  auto map = [](double rpm) { return 558.0 + (rpm - 2500.0) * (-400.0 - 558.0) / 200.0; };
  const double rpm = bisect([&](double r) { return map(r) - std::pow(r * kRpm / 15.0, 2); },
                            2500.0, 2700.0);
  const double pump = std::pow(rpm * kRpm / 15.0, 2);
  std::printf("[measured] stall: %.1f rpm (oracle %.1f), pump %.1f N m (oracle %.1f), turbine "
              "%.1f N m (oracle %.1f)\n",
              pt.engine_rpm(), rpm, pt.engine_torque_nm(), pump, pt.turbine_torque_nm(),
              2 * pump);
  EXPECT_NEAR(rpm, 2550.0, 15.0);  // worked values: near 2550 rpm, 317 N m
  EXPECT_NEAR(pump, 317.0, 3.0);
  EXPECT_NEAR(pt.engine_rpm(), rpm, 0.5);
  EXPECT_NEAR(pt.engine_torque_nm(), pump, 0.002 * pump);
  EXPECT_NEAR(pt.turbine_torque_nm(), 2.0 * pump, 0.002 * 2 * pump);
  EXPECT_EQ(pt.gear(), 1);
}

// Launch from rest on flat ground with the throttle just open (the engine runs on its idle
// governor: what the issue saw as pulling away "at zero throttle") and wide open (on a
// high-friction surface so that the launch is not traction-limited: the published converter
// spins the wheels at mu 0.8). The speed gain over a stretch of first gear against the maps at
// the measured shaft speeds, and the quasi-static acceleration at the start of the stretch.
// Tolerance 5 %: the oracle takes the static tire deflection for the loaded radius (under
// 0.8 g of launch the load transfer moves it by +-7 mm front and rear, about 1.5 %) and the
// wheel spin relative to the chassis (the chassis pitches back by about 1 deg).
TEST(Powertrain, LaunchAccelerationMatchesTheMaps) {
  const auto p = load("hmmwv");
  struct Case {
    double throttle, v0, v1, friction;
  };
  for (const Case c : {Case{0.001, 0.1, 1.0, 0.8}, Case{1.0, 1.0, 4.0, 2.0}}) {
    const auto run_ = launch(p, c.throttle, 8.0, c.friction);
    const SpeedGain g = first_gear_gain(p, run_, c.v0, c.v1);
    std::printf("[measured] launch at throttle %.3f, %.1f to %.1f m/s: speed gain %.3f m/s "
                "(maps %.3f)\n",
                c.throttle, c.v0, c.v1, g.measured, g.predicted);
    EXPECT_NEAR(g.measured, g.predicted, 0.05 * g.predicted) << "throttle " << c.throttle;
  }
  // Pulling away with the throttle just open: quasi-static 0.73 m/s2 at rest (engine on the
  // governor at 750 rpm); the engagement adds a short transient as the engine drops from its
  // unloaded idle (the crank's energy goes into the wheels). Bounded at 0.15 g: the issue saw
  // 0.4 g with the old converter.
  const Body b = body_of(p, 1);
  const ConverterPoint c0 = converter_equilibrium(p, 0.0, 0.001);
  const double a0 = (c0.turbine / 0.04 / (b.r - b.deflection) - b.resistance(p, 0.0)) /
                    (b.mass + b.j_total / ((b.r - b.deflection) * b.r_eff));
  const auto run_ = launch(p, 0.001, 1.0, 0.8);
  double a_max = 0.0;
  for (std::size_t i = 1; i < run_.size(); ++i) {
    a_max = std::max(a_max, (com_speed(p, run_[i]) - com_speed(p, run_[i - 1])) /
                                (run_[i].time_s - run_[i - 1].time_s));
  }
  std::printf("[measured] launch at throttle 0.001: quasi-static %.2f m/s2 at rest, peak over "
              "10 ms %.2f m/s2\n", a0, a_max);
  EXPECT_NEAR(a0, 0.73, 0.02);
  EXPECT_LT(a_max, 0.15 * kGravity);
}

// Throttle just open on flat ground: the vehicle creeps at the speed where the turbine torque
// carries rolling resistance and drag, with the engine on its idle governor. Tolerance 3 %
// (the oracle's tire deflection is the static one; the slip at 380 N is 0.05 %).
TEST(Powertrain, IdleCreepSpeedMatchesTheMaps) {
  const auto p = load("hmmwv");
  const auto run_ = launch(p, 0.001, 40.0, 0.8);
  const double v = forward_speed(run_.back());
  const double v_before = forward_speed(run_[run_.size() - 201]);
  const Body b = body_of(p, 1);
  const double overall = kGears[0] * kFinalDrive;
  // Speed v(w_t) for a turbine speed; the creep speed is where the drive force meets the load.
  auto surplus = [&](double w_t) {
    const ConverterPoint c = converter_equilibrium(p, w_t, 0.001);
    return c.turbine / overall / b.r - b.resistance(p, w_t * overall * b.r_eff);
  };
  const double w_t = bisect(surplus, 10.0, 0.97 * p.engine.idle_rpm * kRpm);
  const double oracle = w_t * overall * b.r_eff;
  std::printf("[measured] idle creep: %.3f m/s (oracle %.3f, speed ratio %.3f), engine %.0f rpm\n",
              v, oracle, w_t / converter_equilibrium(p, w_t, 0.001).w_engine,
              run_.back().engine_speed_rpm);
  EXPECT_LT(std::abs(v - v_before), 0.01);  // settled
  EXPECT_NEAR(v, oracle, 0.03 * oracle);
  EXPECT_EQ(run_.back().gear, 1);
}

// Full throttle on flat ground (mu 0.8): the vehicle speed at each upshift is the upshift
// turbine speed through the gears at the effective rolling radius. Tolerance 2 %: the tire's
// longitudinal slip (about 1 % at the 5 kN of drive force there) and 10 ms sampling.
TEST(Powertrain, UpshiftSpeedsMatchTheGearing) {
  const auto p = load("hmmwv");
  const auto run_ = launch(p, 1.0, 30.0, 0.8);
  const Body b = body_of(p, 1);
  int shifts = 0;
  double last_shift_s = -10.0;
  for (std::size_t i = 1; i < run_.size(); ++i) {
    const int from = run_[i - 1].gear, to = run_[i].gear;
    if (from == to || from == 0) continue;
    ASSERT_EQ(to, from + 1) << "at t = " << run_[i].time_s;
    EXPECT_GE(run_[i].time_s - last_shift_s, 1.0);  // latency
    last_shift_s = run_[i].time_s;
    const double oracle = kUpshiftRpm * kRpm * kGears[from - 1] * kFinalDrive * b.r_eff;
    const double v = forward_speed(run_[i - 1]);
    std::printf("[measured] upshift %d -> %d at %.2f m/s (oracle %.2f), t = %.2f s\n", from, to,
                v, oracle, run_[i].time_s);
    EXPECT_NEAR(v, oracle, 0.02 * oracle);
    ++shifts;
  }
  EXPECT_EQ(shifts, 2);
}
