// The full vehicle on the SCM deformable terrain (common/scm) through the WheelTerrainContact
// hook: it settles into the soil (deeper on softer presets) and drives out of its ruts.
#include <gtest/gtest.h>

#include <cstdio>

#include "scm/scm_terrain.hpp"
#include "vehicle/ode_vehicle.hpp"
#include "vehicle_test_util.hpp"

using namespace syndds;
using namespace syndds::vehicle;
using namespace syndds::vehicle::testing;

TEST(VehicleOnScm, SettlesAndDrivesOnEveryPreset) {
  const auto p = load("hmmwv");
  double last_sinkage = 0.0;
  for (const std::string preset : {"hard", "mid", "soft"}) {
    scm::ScmParams sp;
    sp.soil = scm::soil_preset(preset);
    sp.grid.x_min_m = -5;
    sp.grid.x_max_m = 25;
    sp.grid.y_min_m = -5;
    sp.grid.y_max_m = 5;
    auto soil = std::make_shared<scm::ScmTerrain>(sp);
    OdeVehicleModel m(p, Pose{}, soil, {}, soil);
    const auto d = m.wheel_diagnostics();
    const double sinkage = 0.25 * (d[0].tire_deflection_m + d[1].tire_deflection_m +
                                   d[2].tire_deflection_m + d[3].tire_deflection_m);
    double load = 0.0;
    for (const auto& w : m.snapshot().wheels) load += w.vertical_load_n;
    drive(m, 5.0, 4.0, 0.0);
    const auto s = m.snapshot();
    std::printf("[measured] SCM %s: static sinkage %.3f m, after 5 s at 4 m/s x = %.2f m, "
                "v = %.2f m/s\n",
                preset.c_str(), sinkage, s.pose.position.x(), forward_speed(s));
    EXPECT_NEAR(load, p.total_mass_kg() * kGravity, 0.05 * p.total_mass_kg() * kGravity);
    EXPECT_GT(sinkage, last_sinkage);  // softer soil, deeper
    last_sinkage = sinkage;
    EXPECT_GT(s.pose.position.x(), 10.0);
    EXPECT_TRUE(s.pose.position.allFinite());
  }
}
