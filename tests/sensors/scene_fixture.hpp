#pragma once
// Scenes shared by the sensor tests and the benchmark.
#include <cmath>
#include <limits>

#include "sensors/camera.hpp"
#include "sensors/random.hpp"
#include "sensors/scene.hpp"

namespace syndds::sensors::fixture {

/// A noiseless chase camera of `width` x `height` pixels (the chase rig's default placement).
inline CameraConfig chase_camera(int width, int height) {
  CameraConfig cfg;
  cfg.mode = CameraMode::chase;
  cfg.intrinsics.width = width;
  cfg.intrinsics.height = height;
  cfg.noise = PixelNoiseModel::none;
  return cfg;
}

/// One ray into the scene as the renderer casts it, nothing hidden: what it met first
/// (`geom` RTC_INVALID_GEOMETRY_ID for nothing), at which distance, and the geometric normal.
struct RayHit {
  unsigned geom = RTC_INVALID_GEOMETRY_ID;
  float t = 0.0f;
  Vec3 normal = Vec3::Zero();
  bool hit() const { return geom != RTC_INVALID_GEOMETRY_ID; }
};

inline RayHit cast_ray(const Scene& scene, const Vec3& origin, const Vec3& dir) {
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(origin.x());
  rh.ray.org_y = static_cast<float>(origin.y());
  rh.ray.org_z = static_cast<float>(origin.z());
  rh.ray.dir_x = static_cast<float>(dir.x());
  rh.ray.dir_y = static_cast<float>(dir.y());
  rh.ray.dir_z = static_cast<float>(dir.z());
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  HidingContext ctx;
  init_hiding_context(ctx, -1, false);
  rtcIntersect1(scene.handle(), &ctx.context, &rh);
  return {rh.hit.geomID, rh.ray.tfar, Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z)};
}

/// Rolling terrain (amplitude `hills_m`) of size_m x size_m centred on the origin.
inline TerrainGrid rolling_terrain(double size_m, double spacing_m, double hills_m) {
  const int n = static_cast<int>(std::lround(size_m / spacing_m)) + 1;
  TerrainGrid g = TerrainGrid::flat(Vec2(-0.5 * size_m, -0.5 * size_m), spacing_m, n, n, 0.0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = g.origin.x() + i * spacing_m, y = g.origin.y() + j * spacing_m;
      g.at(i, j) = static_cast<float>(hills_m * (std::sin(0.11 * x) * std::cos(0.07 * y) +
                                                 0.3 * std::sin(0.23 * x + 0.19 * y)));
    }
  }
  return g;
}

/// `count` obstacles (boxes, spheres, cylinders) scattered by a seeded stream, kept off a
/// 12 m corridor along the x axis where the vehicles drive.
inline world::Obstacles scattered_obstacles(int count, double size_m, std::uint64_t seed) {
  NormalRng rng(seed);
  world::Obstacles out;
  for (int k = 0; k < count; ++k) {
    world::Obstacle o;
    o.id = "obstacle";
    o.id += std::to_string(k);
    const int kind = k % 3;
    o.shape = kind == 0 ? world::ShapeKind::box
                        : (kind == 1 ? world::ShapeKind::sphere : world::ShapeKind::cylinder);
    o.label = kind == 0 ? "rock" : (kind == 1 ? "bush" : "tree");
    double x = 0, y = 0;
    do {
      x = (rng.uniform() - 0.5) * (size_m - 10.0);
      y = (rng.uniform() - 0.5) * (size_m - 10.0);
    } while (std::abs(y) < 6.0);
    const double r = 0.5 + 1.5 * rng.uniform();
    o.size =
        kind == 0 ? Vec3(r, r * 0.7, r * 0.5) : (kind == 1 ? Vec3(r, 0, 0) : Vec3(0.3 * r, 0, 3.0));
    o.pose.position = Vec3(x, y, kind == 2 ? 3.0 : 0.3 * r);
    o.pose.orientation = quat_from_yaw(rng.uniform() * 3.0);
    out.push_back(o);
  }
  return out;
}

}  // namespace syndds::sensors::fixture
