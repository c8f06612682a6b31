#include <gtest/gtest.h>

#include "scm/scm_terrain.hpp"
#include "vehicle/ode_vehicle.hpp"

using namespace syndds;

namespace {

struct Outcome {
  double sinkage_m = 0.0;   // ground sinkage under a wheel at rest (0 on rigid ground)
  double speed_mps = 0.0;   // after 8 s at half throttle
};

// The full HMMWV at rest, then at half throttle for 8 s, on rigid ground or on an SCM preset.
Outcome drive(const std::string& preset) {
  const auto params = vehicle::load_vehicle_params(std::string(SYNDDS_TEST_CONFIG_DIR) +
                                                   "/vehicles/hmmwv.yaml");
  std::shared_ptr<const terrain::TerrainSurface> surface;
  std::shared_ptr<scm::ScmTerrain> soil;
  if (preset == "rigid") {
    surface = std::make_shared<terrain::FlatTerrain>(0.0, 0.8);
  } else {
    scm::ScmParams p;
    p.soil = scm::soil_preset(preset);
    p.grid.spacing_m = 0.05;
    p.grid.x_min_m = -5;
    p.grid.x_max_m = 80;
    p.grid.y_min_m = -5;
    p.grid.y_max_m = 5;
    soil = std::make_shared<scm::ScmTerrain>(p);
    surface = soil;
  }
  vehicle::OdeVehicleModel m(params, Pose{}, surface, {}, soil);
  Outcome out;
  if (soil) {
    const Vec3 wheel = m.snapshot().wheels[0].pose.position;
    out.sinkage_m = -soil->height(wheel.x(), wheel.y());  // the undeformed surface is at z = 0
  }
  m.set_inputs({0.0, 0.5, 0.0});
  for (int i = 0; i < 4000; ++i) m.advance(0.002);
  out.speed_mps = m.snapshot().linear_velocity.x();
  return out;
}

}  // namespace

// Softer ground: deeper sinkage, more rolling resistance, lower speed at the same throttle.
TEST(VehicleOnSoil, SoftSinksDeeperAndIsSlowerThanHardThanRigid) {
  const Outcome rigid = drive("rigid");
  const Outcome hard = drive("hard");
  const Outcome soft = drive("soft");
  std::printf("sinkage m: rigid %.4f hard %.4f soft %.4f; speed m/s: %.2f %.2f %.2f\n",
              rigid.sinkage_m, hard.sinkage_m, soft.sinkage_m, rigid.speed_mps, hard.speed_mps,
              soft.speed_mps);
  EXPECT_GT(hard.sinkage_m, rigid.sinkage_m);
  EXPECT_GT(soft.sinkage_m, hard.sinkage_m + 0.05);
  EXPECT_LT(hard.speed_mps, rigid.speed_mps);
  EXPECT_LT(soft.speed_mps, hard.speed_mps);
  EXPECT_GT(soft.speed_mps, 0.5);  // it still moves
}
