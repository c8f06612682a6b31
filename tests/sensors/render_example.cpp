// Renders the benchmark scene for a visual check: a vehicle drives along x over soft soil
// and leaves a rut; writes PNG frames of its front camera and a chase camera, a chase video,
// and one lidar scan as PLY. Run: build/tests/sensors/render_example OUT_DIR
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include "scene_fixture.hpp"
#include "sensors/image_io.hpp"
#include "sensors/rig.hpp"

using namespace syndds;
using namespace syndds::sensors;

int main(int argc, char** argv) {
  const std::string out = argc > 1 ? argv[1] : "render_example";
  Scene scene;
  scene.set_terrain(fixture::rolling_terrain(100.0, 0.1, 0.6), terrain_look("silt"));
  scene.add_obstacles(fixture::scattered_obstacles(30, 100.0, 5));
  for (int v = 0; v < 3; ++v) {
    VehicleShape shape;
    shape.body_colour = vehicle_palette(static_cast<std::size_t>(v));
    scene.add_vehicle("v" + std::to_string(v), shape);
  }
  CameraConfig front;
  front.id = "front";
  front.intrinsics.width = 640;
  front.intrinsics.height = 360;
  front.mount.pose.position = Vec3(2.4, 0, 0.5);
  front.mount.pose.orientation = Quat(Eigen::AngleAxisd(deg_to_rad(5.0), Vec3::UnitY()));
  front.exposure_mode = ExposureMode::instant;
  front.threads = 2;
  CameraConfig chase = front;
  chase.id = "chase";
  chase.mode = CameraMode::chase;
  chase.intrinsics.width = 1280;
  chase.intrinsics.height = 720;
  chase.intrinsics.hfov_rad = deg_to_rad(70.0);
  chase.noise = PixelNoiseModel::none;
  CameraSensor front_cam(front, "v0", 1, 0.01);
  CameraSensor chase_cam(chase, "v0", 2, 0.01);
  LidarConfig lidar_cfg;
  lidar_cfg.mount.pose.position = Vec3(0, 0, 1.1);
  LidarSensor lidar(lidar_cfg, "v0", 3, 0.01);
  VideoWriter video(out + "/chase.avi", 10.0, 1280, 720);

  const auto& g = scene.terrain();
  auto height_at = [&](double x, double y) {
    const int i = static_cast<int>(std::lround((x - g.origin.x()) / g.spacing_m));
    const int j = static_cast<int>(std::lround((y - g.origin.y()) / g.spacing_m));
    return static_cast<double>(g.at(i, j));
  };
  for (int frame = 0; frame < 40; ++frame) {
    const double x = -30.0 + 0.5 * frame;
    // The lead vehicle digs 8 cm ruts under its wheels (two 0.3 m wide tracks).
    std::vector<HeightUpdate> rut;
    for (double track : {-0.91, 0.91}) {
      for (double dx = -0.3; dx <= 0.3; dx += 0.1) {
        for (double dy = -0.15; dy <= 0.15; dy += 0.1) {
          const int i = static_cast<int>(std::lround((x - 1.7 + dx - g.origin.x()) / g.spacing_m));
          const int j = static_cast<int>(std::lround((track + dy - g.origin.y()) / g.spacing_m));
          rut.push_back({i, j,
                         g.at(i, j) > height_at(x - 1.7 + dx, track + dy) - 0.08
                             ? height_at(x - 1.7 + dx, track + dy) - 0.08
                             : g.at(i, j)});
        }
      }
    }
    scene.update_terrain(rut);
    scene.set_vehicle_pose("v0", Pose{Vec3(x, 0, height_at(x, 0) + 0.467), Quat::Identity()}, {});
    scene.set_vehicle_pose(
        "v1", Pose{Vec3(x + 12.0, 0.5, height_at(x + 12.0, 0.5) + 0.467), quat_from_yaw(0.1)}, {});
    scene.set_vehicle_pose(
        "v2", Pose{Vec3(x + 6.0, -6.0, height_at(x + 6.0, -6.0) + 0.467), quat_from_yaw(0.3)}, {});
    scene.commit();
    const RgbImage c = chase_cam.capture(scene, static_cast<std::uint64_t>(frame));
    video.write(c);
    if (frame % 10 == 9) {
      write_png(out + "/chase_" + std::to_string(frame) + ".png", c);
      write_png(out + "/front_" + std::to_string(frame) + ".png",
                front_cam.capture(scene, static_cast<std::uint64_t>(frame)));
    }
  }
  write_ply(out + "/lidar.ply", lidar.scan(scene, 0));

  // Close-ups of one vehicle on flat ground among a rock, a tree and a bush, from the side and
  // from the chase camera: drawn from primitives, then from the meshes of config/meshes.
  for (const bool meshes : {false, true}) {
  SceneConfig studio_config;
  if (meshes) studio_config.mesh_dir = std::string(SYNDDS_CONFIG_DIR) + "/meshes";
  Scene studio(studio_config);
  studio.set_terrain(TerrainGrid::flat(Vec2(-30, -30), 0.5, 121, 121, 0.0), terrain_look("silt"));
  studio.add_vehicle("hmmwv", VehicleShape{});
  studio.set_vehicle_pose("hmmwv", Pose{Vec3(0, 0, 0.467), quat_from_yaw(0.35)}, {});
  world::Obstacles props(3);
  props[0].label = "rock";
  props[0].shape = world::ShapeKind::sphere;
  props[0].size = Vec3(0.8, 0, 0);
  props[0].pose.position = Vec3(5.0, 4.0, 0.8);
  props[1].label = "tree";
  props[1].shape = world::ShapeKind::cylinder;
  props[1].size = Vec3(0.6, 0, 2.5);
  props[1].pose.position = Vec3(-5.0, 6.0, 2.5);
  props[2].label = "bush";
  props[2].shape = world::ShapeKind::sphere;
  props[2].size = Vec3(0.7, 0, 0);
  props[2].pose.position = Vec3(8.0, -1.0, 0.7);
  studio.add_obstacles(props);
  studio.commit();
  const std::string suffix = meshes ? "_meshes.png" : ".png";
  CameraConfig side = chase;
  side.id = "side";
  side.mode = CameraMode::fixed;
  side.intrinsics.width = 640;
  side.intrinsics.height = 360;
  side.mount.pose.position = Vec3(1.5, -9.0, 1.6);
  side.mount.pose.orientation =
      Quat(Eigen::AngleAxisd(std::numbers::pi / 2 + 0.1, Vec3::UnitZ())) *
      Quat(Eigen::AngleAxisd(0.08, Vec3::UnitY()));
  write_png(out + "/vehicle_side" + suffix, CameraSensor(side, "", 4, 0.01).capture(studio, 0));
  CameraConfig behind = chase;
  behind.intrinsics.width = 640;
  behind.intrinsics.height = 360;
  write_png(out + "/vehicle_chase" + suffix,
            CameraSensor(behind, "hmmwv", 5, 0.01).capture(studio, 0));
  }
  video.close();
  std::printf("wrote %s (%d frames), PNGs and lidar.ply in %s\n", video.path().c_str(),
              video.frames(), out.c_str());
  return 0;
}
