// Camera, lidar and radar throughput on a realistic scene: 100 x 100 m terrain at 0.1 m (2 M
// triangles), 4 vehicles, 30 obstacles. Run:
//   build/tests/sensors/bench_sensors [frames] [case] [tile cells] [shadow distance] [meshes]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <string>
#include <vector>

#include "scene_fixture.hpp"
#include "sensors/camera.hpp"
#include "sensors/lidar.hpp"
#include "sensors/radar.hpp"
#include "sensors/rig_config.hpp"

using namespace syndds;
using namespace syndds::sensors;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Median wall time per call (robust against other processes on a shared machine) and the
// median CPU time of the calling thread (the whole cost when running on one thread).
struct Timing {
  double wall = 0.0;
  double cpu = 0.0;
};
template <typename F>
Timing median_seconds(int n, F&& f) {
  std::vector<double> wall, cpu;
  for (int i = 0; i < n; ++i) {
    const auto t0 = Clock::now();
    const double c0 = thread_cpu_seconds();
    f(i);
    cpu.push_back(thread_cpu_seconds() - c0);
    wall.push_back(seconds_since(t0));
  }
  std::sort(wall.begin(), wall.end());
  std::sort(cpu.begin(), cpu.end());
  return {wall[wall.size() / 2], cpu[cpu.size() / 2]};
}

std::string vehicle_name(int v) {
  std::string name = "v";
  name += std::to_string(v);
  return name;
}

void pose_vehicles(Scene& scene, double t) {
  for (int v = 0; v < 4; ++v) {
    Pose p;
    p.position = Vec3(-20.0 + 10.0 * v + 5.0 * t, 1.5 * (v % 2 ? 1 : -1), 0.5);
    p.orientation = quat_from_yaw(0.05 * v);
    scene.set_vehicle_pose(vehicle_name(v), p, {});
  }
}

}  // namespace

int main(int argc, char** argv) {
  const int frames = argc > 1 ? std::stoi(argv[1]) : 20;
  const std::string only = argc > 2 ? argv[2] : "";  // "camera80", "camera1280", "lidar", ...
  SceneConfig scene_cfg;
  if (argc > 3) scene_cfg.terrain_tile_cells = std::stoi(argv[3]);
  if (argc > 4) scene_cfg.shadow_max_distance_m = std::stod(argv[4]);
  // "meshes": obstacles and vehicle bodies from config/meshes, as the shipped camera rigs draw.
  if (argc > 5 && std::string(argv[5]) == "meshes") {
    scene_cfg.mesh_dir = std::string(SYNDDS_CONFIG_DIR) + "/meshes";
  }
  auto t0 = Clock::now();
  Scene scene(scene_cfg);
  scene.set_terrain(fixture::rolling_terrain(100.0, 0.1, 1.0), terrain_look("rigid"));
  scene.add_obstacles(fixture::scattered_obstacles(30, 100.0, 5));
  for (int v = 0; v < 4; ++v) {
    VehicleShape shape;
    shape.body_colour = vehicle_palette(static_cast<std::size_t>(v));
    shape.wheel_positions_m = {Vec3(1.689, 0.91, 0), Vec3(1.689, -0.91, 0), Vec3(-1.689, 0.91, 0),
                               Vec3(-1.689, -0.91, 0)};
    scene.add_vehicle(vehicle_name(v), shape);
  }
  pose_vehicles(scene, 0.0);
  scene.commit();
  std::printf("scene: %zu primitives, build %.3f s\n", scene.primitive_count(), seconds_since(t0));

  // Per-frame scene update cost: move 4 vehicles and dig a 2 m rut (400 vertices).
  {
    std::vector<HeightUpdate> rut;
    const int frames_update = 50;
    auto t1 = Clock::now();
    for (int f = 0; f < frames_update; ++f) {
      rut.clear();
      for (int i = 0; i < 20; ++i) {
        for (int j = 0; j < 20; ++j) rut.push_back({400 + f * 2 + i, 480 + j, -0.05});
      }
      scene.update_terrain(rut);
      pose_vehicles(scene, 0.01 * f);
      scene.commit();
    }
    std::printf("scene update (4 vehicles + 400-vertex rut) + commit: %.3f ms/frame\n",
                1e3 * seconds_since(t1) / frames_update);
  }

  // Deformable soil: a 100 x 20 m grid at 0.05 m drawn every second vertex until it deforms
  // (Scene::set_terrain with coarse stride 2, as the sensor member draws SCM soil); two 0.3 m
  // wide ruts advancing 0.1 m a frame refine a new 3.2 m tile each every 32 frames.
  if (only.empty() || only == "soil") {
    Scene soil(scene_cfg);
    auto t2 = Clock::now();
    soil.set_terrain(TerrainGrid::flat(Vec2(-50.0, -10.0), 0.05, 2001, 401, 0.0),
                     terrain_look("silt"), 2);
    soil.commit();
    std::printf("soil scene (2001 x 401 vertices, stride 2): %zu primitives, build %.3f s\n",
                soil.primitive_count(), seconds_since(t2));
    std::vector<double> plain, refining;
    std::vector<HeightUpdate> rut;
    for (int f = 0; f < 640; ++f) {
      rut.clear();
      for (int track : {182, 218}) {  // y = -0.9 and +0.9 m
        for (int di = 0; di < 2; ++di) {
          for (int dj = -3; dj <= 3; ++dj) rut.push_back({40 + 2 * f + di, track + dj, -0.05});
        }
      }
      const std::size_t fine = soil.fine_terrain_tiles();
      const auto t3 = Clock::now();
      soil.update_terrain(rut);
      soil.commit();
      (soil.fine_terrain_tiles() > fine ? refining : plain).push_back(seconds_since(t3));
    }
    std::sort(plain.begin(), plain.end());
    std::sort(refining.begin(), refining.end());
    std::printf("soil rut frame + commit: %.3f ms median (%zu frames); refining a tile: %.3f ms "
                "median, %.3f ms max (%zu frames); %zu fine tiles, %zu primitives\n",
                1e3 * plain[plain.size() / 2], plain.size(), 1e3 * refining[refining.size() / 2],
                1e3 * refining.back(), refining.size(), soil.fine_terrain_tiles(),
                soil.primitive_count());
  }

  struct Res {
    int w, h;
  };
  for (const Res res : {Res{80, 45}, Res{1280, 720}, Res{1920, 1080}, Res{3840, 2160}}) {
    if (!only.empty() && only != "camera" + std::to_string(res.w)) continue;
    for (int threads : {1, 2}) {
      CameraConfig cfg;
      cfg.intrinsics.width = res.w;
      cfg.intrinsics.height = res.h;
      cfg.threads = threads;
      cfg.mode = CameraMode::fixed;
      cfg.mount.pose.position = Vec3(-30.0, 0.0, 2.0);
      cfg.mount.pose.orientation = Quat(Eigen::AngleAxisd(0.1, Vec3::UnitY()));
      CameraSensor cam(cfg, "", 1, 0.01);
      const int n = res.w <= 80 ? frames * 50 : (res.w > 2000 ? std::max(3, frames / 4) : frames);
      cam.capture(scene, 0);  // warm-up
      const Timing t =
          median_seconds(n, [&](int f) { cam.capture(scene, static_cast<std::uint64_t>(f)); });
      std::printf(
          "camera %4dx%-4d threads %d: %8.3f ms/frame (%7.1f frames/s), caller CPU %8.3f ms\n",
          res.w, res.h, threads, 1e3 * t.wall, 1.0 / t.wall, 1e3 * t.cpu);
    }
  }
  // The default rig's camera: 80 x 45 on the front bumper of vehicle v0, 5 deg down.
  for (int threads : {1, 2}) {
    if (!only.empty() && only != "bumper") continue;
    CameraConfig cfg;
    cfg.threads = threads;
    cfg.mount.pose.position = Vec3(2.4, 0.0, 0.5);
    cfg.mount.pose.orientation = Quat(Eigen::AngleAxisd(deg_to_rad(5.0), Vec3::UnitY()));
    CameraSensor cam(cfg, "v0", 1, 0.01);
    const Timing t = median_seconds(
        frames * 50, [&](int f) { cam.capture(scene, static_cast<std::uint64_t>(f)); });
    std::printf("bumper camera 80x45 threads %d: %8.3f ms/frame, caller CPU %8.3f ms\n", threads,
                1e3 * t.wall, 1e3 * t.cpu);
  }
  for (int threads : {1, 2}) {
    if (!only.empty() && only != "lidar") continue;
    LidarConfig cfg;
    cfg.threads = threads;
    cfg.mount.pose.position = Vec3(0, 0, 2.2);
    LidarSensor lidar(cfg, "", 1, 0.01);
    lidar.scan(scene, 0);
    const int n = frames * 5;
    std::size_t points = 0;
    const double per = median_seconds(n, [&](int f) {
                         points += lidar.scan(scene, static_cast<std::uint64_t>(f)).points.size();
                       }).wall;
    std::printf(
        "lidar 900x16 threads %d: %.3f ms/scan, %.2f M beams/s, %.2f M points/s (%zu pts/scan)\n",
        threads, 1e3 * per, 14400 / per * 1e-6, static_cast<double>(points) / n / per * 1e-6,
        points / static_cast<std::size_t>(n));
    cfg.beam_samples = 5;
    LidarSensor div(cfg, "", 1, 0.01);
    const double per2 =
        median_seconds(n, [&](int f) { div.scan(scene, static_cast<std::uint64_t>(f)); }).wall;
    std::printf("lidar 900x16x5 sub-rays threads %d: %.3f ms/scan, %.2f M rays/s\n", threads,
                1e3 * per2, 72000 / per2 * 1e-6);
  }
  for (int threads : {1, 2}) {
    if (!only.empty() && only != "radar") continue;
    // The example rig's forward radar (config/sensors/convoy_radar.yaml: 200 x 50 rays, 150 m),
    // standing behind the four vehicles, which drive away at 5 m/s.
    RadarConfig cfg =
        load_sensor_rig(std::string(SYNDDS_CONFIG_DIR) + "/sensors/convoy_radar.yaml").radars.at(0);
    cfg.threads = threads;
    cfg.mount.pose.position = Vec3(-30, 0, 1.1);
    for (int v = 0; v < 4; ++v) scene.set_vehicle_velocity(vehicle_name(v), Vec3(5, 0, 0), Vec3::Zero());
    RadarSensor radar(cfg, "", 1, 0.01);
    radar.scan(scene, 0);
    const int n = frames * 5;
    std::size_t detections = 0;
    const auto t = median_seconds(n, [&](int f) {
      detections += radar.scan(scene, static_cast<std::uint64_t>(f)).detections.size();
    });
    std::printf("radar %dx%d threads %d: %.3f ms/scan, %.2f M rays/s, caller CPU %.3f ms "
                "(%zu detections/scan)\n",
                cfg.horizontal_rays, cfg.vertical_rays, threads, 1e3 * t.wall,
                radar.rays() / t.wall * 1e-6, 1e3 * t.cpu, detections / static_cast<std::size_t>(n));
  }
  return 0;
}
