// The deformable-terrain hook: with a WheelTerrainContact the wheel-ground forces come from it
// (here a fake: a linear spring ground, optionally with a push and a spin torque).
#include <gtest/gtest.h>

#include <cstdio>

#include "vehicle/ode_vehicle.hpp"
#include "vehicle_test_util.hpp"

using namespace syndds;
using namespace syndds::vehicle;
using namespace syndds::vehicle::testing;

namespace {

/// Ground z = 0 as a vertical spring-damper under the wheel's lowest point.
class SpringGround final : public terrain::WheelTerrainContact {
 public:
  double stiffness_npm = 2.0e5;
  double damping_nspm = 4.0e3;
  Vec3 push_n = Vec3::Zero();        // extra force on every wheel in contact
  double spin_torque_nm = 0.0;       // extra torque about every wheel's spin axis
  long calls = 0;
  std::size_t last_count = 0;
  double last_dt = 0.0;

  void compute_wheel_loads(std::span<const terrain::WheelBodyState> wheels, double dt,
                           std::span<terrain::WheelLoad> loads) override {
    ++calls;
    last_count = wheels.size();
    last_dt = dt;
    for (std::size_t i = 0; i < wheels.size(); ++i) {
      const auto& w = wheels[i];
      const double sink = w.radius_m - w.pose.position.z();
      terrain::WheelLoad l;
      if (sink > 0) {
        const double fz =
            std::max(0.0, stiffness_npm * sink - damping_nspm * w.linear_velocity.z());
        l.force = Vec3(0, 0, fz) + push_n;
        l.torque = spin_torque_nm * (w.pose.orientation * Vec3::UnitY());
        l.sinkage_m = sink;
        l.in_contact = true;
      }
      loads[i] = l;
    }
  }
};

}  // namespace

// At rest on the spring ground each wheel sinks W / k, and the snapshot's loads are the fake's.
TEST(DeformableHook, WheelLoadsComeFromTheTerrain) {
  const auto p = load("hmmwv");
  auto ground = std::make_shared<SpringGround>();
  OdeVehicleModel m(p, Pose{}, flat(), {}, ground);
  EXPECT_GT(ground->calls, 0);
  EXPECT_EQ(ground->last_count, 4u);
  EXPECT_DOUBLE_EQ(ground->last_dt, 0.002);
  const long before = ground->calls;
  run(m, 1.0);
  EXPECT_EQ(ground->calls - before, 500);
  const auto s = m.snapshot();
  const auto d = m.wheel_diagnostics();
  double total = 0.0;
  for (int i = 0; i < 4; ++i) {
    const double load = p.static_wheel_load_n(i < 2);
    const double sink = load / ground->stiffness_npm;
    EXPECT_NEAR(p.wheels.radius_m - s.wheels[i].pose.position.z(), sink, 0.02 * sink);
    EXPECT_NEAR(d[i].tire_deflection_m, sink, 0.02 * sink);
    EXPECT_NEAR(s.wheels[i].vertical_load_n, load, 0.02 * load);
    total += s.wheels[i].vertical_load_n;
  }
  EXPECT_NEAR(total, p.total_mass_kg() * kGravity, 1e-3 * total);
}

// Forces and torques returned by the terrain are applied to the wheel bodies: a push moves
// the vehicle at F / m, a spin torque spins the (free, neutral) wheels at T / J (J with the drive shaft's share).
TEST(DeformableHook, ForcesAndTorquesAreApplied) {
  auto p = load("hmmwv");
  p.chassis.drag_area_m2 = 0.0;
  auto ground = std::make_shared<SpringGround>();
  OdeVehicleModel m(p, Pose{}, flat(), {}, ground);
  ground->push_n = Vec3(500.0, 0.0, 0.0);
  run(m, 2.0);
  const double v = forward_speed(m.snapshot());
  const double expected = 4 * 500.0 / p.total_mass_kg() * 2.0;
  std::printf("[measured] push 4 x 500 N for 2 s: %.4f m/s (F t / m = %.4f)\n", v, expected);
  EXPECT_NEAR(v, expected, 0.02 * expected);
  for (const auto& w : m.snapshot().wheels) EXPECT_NEAR(w.spin_rad_s, 0.0, 1e-6);

  ground->push_n.setZero();
  ground->spin_torque_nm = 10.0;
  const double spin0 = m.snapshot().wheels[0].spin_rad_s;
  run(m, 1.0);
  const double spin = m.snapshot().wheels[0].spin_rad_s - spin0;
  // In neutral the drive shaft still turns with the wheels: each gets a quarter of its inertia.
  const double j = p.wheels.spin_inertia_kgm2 + 0.25 * p.driveline_inertia_at_wheels_kgm2(0);
  const double expected_spin = 10.0 / j * 1.0;
  EXPECT_NEAR(spin, expected_spin, 0.02 * expected_spin);
}
