// Benchmark (not a test): cost of one dynamics step and real-time factor (wall / simulated
// time) of one vehicle on flat rigid ground at step 2 ms, full (ODE) and reduced (bicycle)
// models; the full model also with 34 obstacles far from its path (broad phase every step),
// on a 513 x 513 height map, pushing against a wall (contact joints every step), and with 1
// and 8 other vehicles within reach (peers rebuilt every 10 ms frame, docs/vehicle-contact.md).
//
//   bench_vehicle [simulated_seconds=120] [vehicle=hmmwv]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "terrain/heightmap_terrain.hpp"
#include "vehicle/bicycle_model.hpp"
#include "vehicle/ode_vehicle.hpp"

using namespace syndds;
using namespace syndds::vehicle;

namespace {

constexpr double kStep = 0.002;

struct Result {
  double us_per_step;
  double rtf;
  double distance_m;
};

/// Drives a gentle slalom at part throttle; the driver updates every 10 ms like a frame.
Result measure(VehicleModel& m, double seconds) {
  const long steps = std::lround(seconds / kStep);
  const Vec3 start = m.snapshot().pose.position;
  const auto t0 = std::chrono::steady_clock::now();
  for (long i = 0; i < steps; ++i) {
    if (i % 5 == 0) {
      const double t = i * kStep;
      const double v = m.snapshot().speed_mps();
      m.set_inputs({0.2 * std::sin(0.5 * t), v < 12.0 ? 0.6 : 0.0, v > 14.0 ? 0.2 : 0.0});
    }
    m.advance(kStep);
  }
  const auto t1 = std::chrono::steady_clock::now();
  const double wall = std::chrono::duration<double>(t1 - t0).count();
  return {wall / static_cast<double>(steps) * 1e6, wall / seconds,
          (m.snapshot().pose.position - start).norm()};
}

/// As measure, with other vehicles around it: every frame (5 steps) each becomes a peer at
/// `offsets` (x ahead, y left, in the vehicle's frame) moving with the vehicle, as the
/// vehicle agent hands them on (docs/vehicle-contact.md). Offsets 5.0 m ahead or 3.1 m aside
/// keep the footprints 0.3 m apart: within reach (proxies built, narrow phase every step), no
/// contact.
Result measure_with_peers(VehicleModel& m, double seconds, const std::vector<Vec2>& offsets,
                          const std::shared_ptr<const VehicleParams>& params) {
  const long steps = std::lround(seconds / kStep);
  const Vec3 start = m.snapshot().pose.position;
  const auto t0 = std::chrono::steady_clock::now();
  for (long i = 0; i < steps; ++i) {
    if (i % 5 == 0) {
      const VehicleSnapshot s = m.snapshot();
      const double t = i * kStep;
      const double v = s.speed_mps();
      m.set_inputs({0.2 * std::sin(0.5 * t), v < 12.0 ? 0.6 : 0.0, v > 14.0 ? 0.2 : 0.0});
      std::vector<PeerVehicle> peers;
      for (std::size_t k = 0; k < offsets.size(); ++k) {
        PeerVehicle p;
        p.id = "peer" + std::to_string(k);
        p.params = params;
        p.pose = s.pose;
        p.pose.position += s.pose.orientation * Vec3(offsets[k].x(), offsets[k].y(), 0.0);
        p.linear_velocity = s.linear_velocity;
        p.angular_velocity = s.angular_velocity;
        for (const auto& w : s.wheels) {
          Pose wp = w.pose;
          wp.position += s.pose.orientation * Vec3(offsets[k].x(), offsets[k].y(), 0.0);
          p.wheels.push_back(wp);
        }
        peers.push_back(std::move(p));
      }
      m.set_peers(std::move(peers));
    }
    m.advance(kStep);
  }
  const auto t1 = std::chrono::steady_clock::now();
  const double wall = std::chrono::duration<double>(t1 - t0).count();
  return {wall / static_cast<double>(steps) * 1e6, wall / seconds,
          (m.snapshot().pose.position - start).norm()};
}

std::shared_ptr<terrain::HeightmapTerrain> hills() {
  const int n = 513;
  std::vector<double> h(static_cast<std::size_t>(n) * n);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      h[static_cast<std::size_t>(j) * n + i] = 0.5 * std::sin(i * 0.05) * std::cos(j * 0.04);
    }
  }
  return std::make_shared<terrain::HeightmapTerrain>(n, n, std::move(h), 1024.0, 1024.0);
}

world::Obstacles obstacles() {
  world::Obstacles out;
  for (int k = 0; k < 34; ++k) {
    world::Obstacle o;
    o.id = "rock" + std::to_string(k);
    o.shape = k % 3 == 0 ? world::ShapeKind::box
                         : (k % 3 == 1 ? world::ShapeKind::sphere : world::ShapeKind::cylinder);
    o.size = Vec3(1.0, 1.0, 1.0);
    o.pose.position = Vec3(20.0 * (k / 2), k % 2 == 0 ? 2000.0 : -2000.0, 0.5);
    out.push_back(o);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  const double seconds = argc > 1 ? std::atof(argv[1]) : 120.0;
  const std::string name = argc > 2 ? argv[2] : "hmmwv";
  const auto params = load_vehicle_params(std::string(SYNDDS_CONFIG_DIR) + "/vehicles/" + name +
                                          ".yaml");
  auto flat = std::make_shared<terrain::FlatTerrain>(0.0, 0.8);
  std::printf("vehicle %s, step %.3f s, %.0f s simulated per case, one thread\n", name.c_str(),
              kStep, seconds);
  std::printf("%-34s %12s %10s %10s\n", "case", "us/step", "RTF", "path m");
  auto report = [](const char* label, const Result& r) {
    std::printf("%-34s %12.2f %10.5f %10.0f\n", label, r.us_per_step, r.rtf, r.distance_m);
  };
  {
    const auto t0 = std::chrono::steady_clock::now();
    OdeVehicleModel m(params, Pose{}, flat);
    const auto t1 = std::chrono::steady_clock::now();
    std::printf("full model construction + %.1f s settling: %.1f ms\n",
                OdeVehicleModel::kSettleTimeS,
                std::chrono::duration<double, std::milli>(t1 - t0).count());
    report("full (ODE), flat rigid", measure(m, seconds));
  }
  {
    OdeVehicleModel m(params, Pose{}, flat, obstacles());
    report("full (ODE), flat + 34 obstacles", measure(m, seconds));
  }
  {
    OdeVehicleModel m(params, Pose{}, hills());
    report("full (ODE), 513^2 height map", measure(m, seconds));
  }
  {
    world::Obstacle wall;
    wall.id = "wall";
    wall.size = Vec3(0.5, 10.0, 1.5);
    wall.pose.position = Vec3(12.0, 0.0, 1.5);
    OdeVehicleModel m(params, Pose{}, flat, {wall});
    report("full (ODE), pushing against a wall", measure(m, seconds));
  }
  const auto shared = std::make_shared<const VehicleParams>(params);
  const std::vector<Vec2> one = {{5.0, 0.0}};
  const std::vector<Vec2> eight = {{5.0, 0.0},  {-5.0, 0.0}, {0.0, 3.1},  {0.0, -3.1},
                                   {5.0, 3.1},  {5.0, -3.1}, {-5.0, 3.1}, {-5.0, -3.1}};
  {
    OdeVehicleModel m(params, Pose{}, flat);
    report("full (ODE), 1 vehicle within reach", measure_with_peers(m, seconds, one, shared));
  }
  {
    OdeVehicleModel m(params, Pose{}, flat);
    report("full (ODE), 8 vehicles within reach", measure_with_peers(m, seconds, eight, shared));
  }
  {
    BicycleModel m(params, Pose{}, flat);
    report("reduced (bicycle), flat rigid", measure(m, seconds));
  }
  {
    BicycleModel m(params, Pose{}, flat);
    report("reduced, 8 vehicles within reach", measure_with_peers(m, seconds, eight, shared));
  }
  return 0;
}
