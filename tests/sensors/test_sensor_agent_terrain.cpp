// The sensor member's scene shows the soil at the soil's own spacing where it deformed: a
// deformation at a vertex between the 0.1 m render points (odd SCM indices on a 0.05 m grid) is
// drawn (it used to be dropped: the soil was drawn at every second vertex, ruts as a
// staircase), while untouched soil stays coarse.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include "agents/sensor_agent.hpp"
#include "scenario/scenario.hpp"

using namespace syndds;

namespace {

namespace fs = std::filesystem;

proto::FrameContext context(std::int64_t frame) {
  proto::FrameContext ctx;
  ctx.frame = frame;
  ctx.heartbeat_s = 0.01;
  ctx.sim_time_s = static_cast<double>(frame) * ctx.heartbeat_s;
  return ctx;
}

scenario::Scenario scm_scenario(const fs::path& dir) {
  fs::create_directories(dir);
  const fs::path file = dir / "scenario.yaml";
  std::ofstream(file) << R"(name: sensor_terrain
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1.0}
terrain:
  type: scm
  preset: mid
  spacing_m: 0.05
  area: {x_min_m: -5, x_max_m: 15, y_min_m: -5, y_max_m: 5}
vehicles:
  - id: a
    model: hmmwv
    start: {x: 0, y: 0, yaw_deg: 0}
    sensors: {rig: default}
)";
  return scenario::load_scenario(file.string(), {}, SYNDDS_TEST_CONFIG_DIR);
}

// Height of the drawn surface straight below (x, y), NaN if nothing is there.
double drawn_height(const sensors::Scene& scene, double x, double y) {
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(x);
  rh.ray.org_y = static_cast<float>(y);
  rh.ray.org_z = 5.0f;
  rh.ray.dir_z = -1.0f;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  sensors::HidingContext ctx;
  // Hide the vehicle standing at the origin: only the ground counts.
  sensors::init_hiding_context(ctx, scene.vehicle_slot("a"), false);
  rtcIntersect1(scene.handle(), &ctx.context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::numeric_limits<double>::quiet_NaN();
  return 5.0 - rh.ray.tfar;
}

}  // namespace

TEST(SensorAgentTerrain, RutsAreDrawnAtTheSoilSpacing) {
  const fs::path dir = fs::path(testing::TempDir()) / "syndds-sensor-agent-terrain";
  fs::remove_all(dir);
  const auto s = scm_scenario(dir);
  agents::SensorAgent sensor(s, s.vehicles.front(), {(dir / "out").string()});
  const std::size_t tiles = sensor.scene().terrain_tiles();
  EXPECT_EQ(sensor.scene().fine_terrain_tiles(), 0u);  // untouched soil is drawn coarse

  proto::FrameSamples out;
  sensor.step(context(0), {}, out);
  // A rut along x = 5..7 m, y = 1 m whose depth alternates from one SCM vertex to the next:
  // 3 cm at even i, 9 cm at odd i (vertex (i, j) at (0.05 i, 0.05 j)).
  proto::TerrainDeformationMsg d;
  d.vehicle_id = "a";
  d.source = "vehicle/a";
  d.frame = 0;
  d.spacing_m = 0.05;
  for (std::int32_t i = 100; i <= 140; ++i) {
    for (std::int32_t j = 17; j <= 23; ++j) {
      const double level = i % 2 ? -0.09 : -0.03;
      d.vertices.push_back({i, j, level, 0.0, -level, 1.0e5});
    }
  }
  proto::FrameSamples in;
  in.terrain_deformations.push_back(d);
  sensor.step(context(1), in, out);

  const auto& scene = sensor.scene();
  EXPECT_GE(scene.fine_terrain_tiles(), 1u);
  EXPECT_LE(scene.fine_terrain_tiles(), 2u);
  EXPECT_EQ(scene.terrain_tiles(), tiles);
  for (std::int32_t i = 101; i < 140; ++i) {
    // A hair off the vertex along y (exactly on it four quads meet).
    const double z = drawn_height(scene, 0.05 * i, 0.05 * 20 + 1e-4);
    EXPECT_NEAR(z, i % 2 ? -0.09 : -0.03, 2e-3) << "vertex " << i << ", 20";
  }
  // Untouched soil far away: the flat base.
  EXPECT_NEAR(drawn_height(scene, 12.0, -3.0), 0.0, 1e-6);
}
