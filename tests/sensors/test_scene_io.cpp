#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "sensors/camera.hpp"
#include "sensors/image_io.hpp"
#include "sensors/lidar.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {
std::filesystem::path temp_dir(const std::string& name) {
  auto p = std::filesystem::temp_directory_path() / ("syndds_sensors_" + name);
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

RgbImage checker(int size, std::array<std::uint8_t, 3> a, std::array<std::uint8_t, 3> b) {
  RgbImage img;
  img.width = img.height = size;
  for (int v = 0; v < size; ++v) {
    for (int u = 0; u < size; ++u) {
      const auto& c = ((u < size / 2) == (v < size / 2)) ? a : b;
      img.pixels.insert(img.pixels.end(), c.begin(), c.end());
    }
  }
  return img;
}
}  // namespace

TEST(SceneTerrain, SampledGridIsWorldAnchoredForScmUpdates) {
  const terrain::FlatTerrain ground(0.3);
  const TerrainGrid g = sample_terrain(ground, 0.5, -2.2, 3.0, -1.0, 1.0);
  EXPECT_DOUBLE_EQ(g.origin.x(), -2.0);
  EXPECT_DOUBLE_EQ(g.origin.y(), -1.0);
  EXPECT_EQ(g.nx, 11);
  EXPECT_EQ(g.ny, 5);
  EXPECT_FLOAT_EQ(g.at(10, 4), 0.3f);
  Scene scene;
  scene.set_terrain(g, terrain_look("rigid"));
  // World vertex (-4, -2) is (-2.0 m, -1.0 m): the grid's first vertex.
  const std::vector<HeightUpdate> u{{-4, -2, -0.1}, {2, 0, -0.2}, {100, 0, 1.0}};
  EXPECT_EQ(scene.update_terrain_world(u), 2u);
  EXPECT_FLOAT_EQ(scene.terrain().at(0, 0), -0.1f);
  EXPECT_FLOAT_EQ(scene.terrain().at(6, 2), -0.2f);
  scene.commit();
  EXPECT_EQ(scene.dirty_tiles_last_commit(), 1u);
  const std::vector<HeightUpdate> bad{{1, 1, std::nan("")}};
  EXPECT_THROW(scene.update_terrain(bad), std::invalid_argument);
  scene.add_vehicle("v", VehicleShape{});
  EXPECT_THROW(scene.set_vehicle_pose("v", Pose{Vec3(0, std::nan(""), 0), Quat::Identity()}, {}),
               std::invalid_argument);
  EXPECT_THROW(scene.set_vehicle_pose("v", Pose{Vec3::Zero(), Quat(2, 0, 0, 0)}, {}),
               std::invalid_argument);
  EXPECT_THROW(scene.set_vehicle_pose("w", Pose{}, {}), std::invalid_argument);
  EXPECT_THROW(scene.add_vehicle("v", VehicleShape{}), std::invalid_argument);
  TerrainGrid off = TerrainGrid::flat(Vec2(0.25, 0.0), 0.5, 4, 4, 0.0);
  scene.set_terrain(off, terrain_look("rigid"));
  EXPECT_THROW(scene.update_terrain_world(u), std::logic_error);
  EXPECT_THROW(terrain_look("lava"), std::invalid_argument);
}

TEST(SceneTerrain, TextureImageColoursTheGround) {
  const auto dir = temp_dir("texture");
  const std::string file = (dir / "checker.png").string();
  write_png(file, checker(16, {255, 0, 0}, {0, 255, 0}));
  TerrainLook look;
  look.texture_file = file;
  look.texture_size_m = 2.0;  // one repeat: 2 m, so 1 m squares
  Scene scene;
  scene.set_terrain(TerrainGrid::flat(Vec2(-10, -10), 0.5, 41, 41, 0.0), look);
  scene.commit();
  // Texel centres: the top-left quarter of the image is the north-west square of a repeat.
  const Rgb nw = scene.terrain_albedo(0.5f, 1.5f), ne = scene.terrain_albedo(1.5f, 1.5f);
  EXPECT_NEAR(nw.r, 1.0f, 1e-5);
  EXPECT_NEAR(nw.g, 0.0f, 1e-5);
  EXPECT_NEAR(ne.g, 1.0f, 1e-5);
  EXPECT_NEAR(ne.r, 0.0f, 1e-5);
  CameraConfig cfg;
  cfg.mode = CameraMode::fixed;
  cfg.noise = PixelNoiseModel::none;
  cfg.intrinsics.width = 64;
  cfg.intrinsics.height = 36;
  cfg.mount.pose.position = Vec3(0.3, 0.2, 4.0);
  cfg.mount.pose.orientation = Quat(Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitY()));
  CameraSensor cam(cfg, "", 1, 0.01);
  const RgbImage img = cam.capture(scene, 0);
  int red = 0, green = 0;
  for (std::size_t i = 0; i < img.pixels.size(); i += 3) {
    red += img.pixels[i] > 150 && img.pixels[i + 1] < 90;
    green += img.pixels[i + 1] > 150 && img.pixels[i] < 90;
  }
  EXPECT_GT(red, 500);
  EXPECT_GT(green, 500);
  look.texture_file = (dir / "missing.png").string();
  EXPECT_THROW(scene.set_terrain(TerrainGrid::flat(Vec2(0, 0), 1, 2, 2, 0), look),
               std::invalid_argument);
}

TEST(SensorOutput, PngRoundTripVideoAndPly) {
  const auto dir = temp_dir("output");
  const RgbImage img = checker(32, {10, 200, 30}, {250, 5, 120});
  const std::string png = (dir / "frames" / "f0.png").string();
  write_png(png, img);
  const RgbImage back = read_image(png);
  EXPECT_EQ(back.width, 32);
  EXPECT_EQ(back.pixels, img.pixels);  // lossless

  {
    VideoWriter video((dir / "run.avi").string(), 30.0, 32, 32);
    for (int k = 0; k < 10; ++k) video.write(img);
    EXPECT_EQ(video.frames(), 10);
    EXPECT_THROW(video.write(checker(16, {0, 0, 0}, {1, 1, 1})), std::runtime_error);
    video.close();
    EXPECT_GT(std::filesystem::file_size(video.path()), 1000u);
  }

  LidarScan scan;
  scan.sensor_id = "lidar";
  scan.points.push_back({1, 2, 3, 0.5f, 3.74f, 4, 7});
  const std::string ply = (dir / "scan.ply").string();
  write_ply(ply, scan);
  std::ifstream in(ply);
  std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(all.find("element vertex 1"), std::string::npos);
  EXPECT_NE(all.find("1 2 3 0.5 3.74 4 7"), std::string::npos);
}
