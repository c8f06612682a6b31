#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "scene_fixture.hpp"
#include "sensors/lidar.hpp"
#include "sensors/ray_packets.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {

constexpr double kFrame = 0.01;

// A wall whose front face is the plane x = distance (20 m wide each side, 10 m up/down).
world::Obstacle wall(double distance, double half_width = 30.0, double y_centre = 0.0) {
  world::Obstacle o;
  o.id = "wall";
  o.label = "wall";
  o.shape = world::ShapeKind::box;
  o.size = Vec3(0.5, half_width, 10.0);
  o.pose.position = Vec3(distance + 0.5, y_centre, 0.0);
  return o;
}

LidarConfig front_lidar() {
  LidarConfig c;
  c.channels = 16;
  c.samples = 200;
  c.hfov_min_deg = -30.0;
  c.hfov_max_deg = 30.0;
  c.vfov_min_deg = -15.0;
  c.vfov_max_deg = 15.0;
  c.angle_noise_std_rad = 0.0;
  return c;
}

struct Stats {
  double mean = 0.0, std = 0.0;
  std::size_t n = 0;
};
Stats stats(const std::vector<double>& v) {
  Stats s;
  s.n = v.size();
  for (double x : v) s.mean += x;
  s.mean /= static_cast<double>(v.size());
  for (double x : v) s.std += (x - s.mean) * (x - s.mean);
  s.std = std::sqrt(s.std / static_cast<double>(v.size() - 1));
  return s;
}

}  // namespace

TEST(Lidar, BeamGeometryFollowsTheFieldOfView) {
  LidarConfig c;  // VLP-16-like: 16 channels -15..15 deg, 900 samples over a full turn
  const LidarRenderer r(c);
  EXPECT_NEAR(r.elevation_rad(0), deg_to_rad(-15.0), 1e-12);
  EXPECT_NEAR(r.elevation_rad(1), deg_to_rad(-13.0), 1e-12);
  EXPECT_NEAR(r.elevation_rad(15), deg_to_rad(15.0), 1e-12);
  EXPECT_NEAR(r.azimuth_rad(0), -std::numbers::pi, 1e-12);
  EXPECT_NEAR(r.azimuth_rad(899), std::numbers::pi - deg_to_rad(0.4), 1e-12);  // no duplicate
  const LidarRenderer f(front_lidar());
  EXPECT_NEAR(f.azimuth_rad(199), deg_to_rad(30.0), 1e-12);  // partial span: both ends
  c.max_range_m = 0.1;
  EXPECT_THROW(LidarRenderer{c}, std::invalid_argument);
}

// Ranges to a wall at known distance: mean error ~ 0 and std = configured range noise.
TEST(Lidar, WallRangesMatchWithinConfiguredNoise) {
  Scene scene;
  scene.add_obstacle(wall(20.0));
  scene.commit();
  LidarConfig cfg = front_lidar();
  cfg.range_noise_std_m = 0.01;
  LidarSensor lidar(cfg, "", derive_seed(42, "lead/lidar"), kFrame);
  const LidarRenderer& r = lidar.renderer();
  std::vector<double> residual;
  for (std::uint64_t scan = 0; scan < 4; ++scan) {
    const LidarScan s = lidar.scan(scene, scan);
    ASSERT_EQ(s.points.size(), 3200u);  // every beam hits the wall
    for (const auto& p : s.points) {
      const double expected =
          20.0 / (std::cos(r.elevation_rad(p.channel)) * std::cos(r.azimuth_rad(p.sample)));
      residual.push_back(p.range - expected);
      // Without angle noise the point lies on the wall plane up to the range noise.
      EXPECT_NEAR(p.x, 20.0, 6.0 * 0.01);
    }
  }
  const Stats st = stats(residual);
  EXPECT_NEAR(st.mean, 0.0, 4.0 * 0.01 / std::sqrt(static_cast<double>(st.n)));
  EXPECT_NEAR(st.std, 0.01, 0.05 * 0.01);
}

TEST(Lidar, AngleNoiseMovesReportedDirections) {
  Scene scene;
  scene.add_obstacle(wall(20.0));
  scene.commit();
  LidarConfig cfg = front_lidar();
  cfg.range_noise_std_m = 0.0;
  cfg.angle_noise_std_rad = 0.002;
  LidarSensor lidar(cfg, "", 9, kFrame);
  std::vector<double> daz, del;
  for (std::uint64_t scan = 0; scan < 4; ++scan) {
    for (const auto& p : lidar.scan(scene, scan).points) {
      daz.push_back(std::atan2(p.y, p.x) - lidar.renderer().azimuth_rad(p.sample));
      del.push_back(std::asin(p.z / p.range) - lidar.renderer().elevation_rad(p.channel));
    }
  }
  EXPECT_NEAR(stats(daz).std, 0.002, 0.05 * 0.002);
  EXPECT_NEAR(stats(del).std, 0.002, 0.05 * 0.002);
}

TEST(Lidar, GroundRangeAndIntensityFromIncidence) {
  Scene scene;
  scene.set_terrain(TerrainGrid::flat(Vec2(-60, -60), 0.5, 241, 241, 0.0), terrain_look("rigid"));
  scene.add_obstacle(wall(10.0));
  scene.commit();
  LidarConfig cfg = front_lidar();
  cfg.range_noise_std_m = 0.0;
  cfg.mount.pose.position = Vec3(0, 0, 2.0);
  LidarSensor lidar(cfg, "", 1, kFrame);
  const LidarScan s = lidar.scan(scene, 0);
  const float wall_reflectance = scene.config().obstacle_reflectance;
  const float ground_reflectance = terrain_look("rigid").reflectance;
  int ground = 0, on_wall = 0;
  for (const auto& p : s.points) {
    const double el = lidar.renderer().elevation_rad(p.channel);
    const double az = lidar.renderer().azimuth_rad(p.sample);
    const double to_ground = 2.0 / std::sin(-el);
    const double to_wall = 10.0 / (std::cos(el) * std::cos(az));
    if (el < 0.0 && to_ground < to_wall) {  // the beam meets the ground first
      ++ground;
      EXPECT_NEAR(p.range, to_ground, 1e-3);
      EXPECT_NEAR(p.intensity, ground_reflectance * std::sin(-el), 1e-4);
    } else {
      ++on_wall;
      EXPECT_NEAR(p.range, to_wall, 1e-3);
      EXPECT_NEAR(p.intensity, wall_reflectance * std::cos(el) * std::cos(az), 1e-4);
    }
  }
  EXPECT_GT(ground, 500);
  EXPECT_GT(on_wall, 500);
  EXPECT_EQ(ground + on_wall, 3200);
}

TEST(Lidar, MaxRangeAndReturnModesOfDivergentBeams) {
  // A near wall covering y > 0.05 m at 10 m in front of a far wall at 20 m: a beam aimed at the
  // edge splits its sub-rays between them.
  Scene scene;
  scene.add_obstacle(wall(10.0, 10.0, 10.05));  // covers y from 0.05 m
  scene.add_obstacle(wall(20.0));
  scene.commit();
  LidarConfig cfg;
  cfg.channels = 1;
  cfg.samples = 1;
  cfg.vfov_min_deg = cfg.vfov_max_deg = 0.0;
  cfg.hfov_min_deg = cfg.hfov_max_deg = 0.0;
  cfg.range_noise_std_m = 0.0;
  cfg.angle_noise_std_rad = 0.0;
  cfg.divergence_rad = 0.02;
  cfg.beam_samples = 9;  // centre + 8 on the ring: ring rays at +y hit the near wall
  auto range_for = [&](LidarReturnMode mode, double max_range) {
    cfg.return_mode = mode;
    cfg.max_range_m = max_range;
    LidarSensor l(cfg, "", 1, kFrame);
    const auto s = l.scan(scene, 0);
    return s.points.empty() ? -1.0 : static_cast<double>(s.points[0].range);
  };
  EXPECT_NEAR(range_for(LidarReturnMode::nearest, 100.0), 10.0, 1e-3);
  const double mean = range_for(LidarReturnMode::mean, 100.0);
  EXPECT_NEAR(mean, (3 * 10.0 + 6 * 20.0) / 9.0, 0.01);  // 3 of 9 rays on the near wall
  // Strongest: the centre ray meets the far wall head on (cos 1); ring rays are 0.01 rad off.
  EXPECT_NEAR(range_for(LidarReturnMode::strongest, 100.0), 20.0, 1e-3);
  EXPECT_NEAR(range_for(LidarReturnMode::mean, 15.0), 10.0, 1e-3);  // far wall out of range
  cfg.beam_samples = 1;
  EXPECT_NEAR(range_for(LidarReturnMode::nearest, 100.0), 20.0, 1e-3);  // centre ray only
  EXPECT_LT(range_for(LidarReturnMode::nearest, 15.0), 0.0);            // nothing in range
}

TEST(Lidar, HidesOwnVehicleSeesOthersAndIsDeterministicAcrossThreads) {
  Scene scene;
  scene.set_terrain(fixture::rolling_terrain(60.0, 0.25, 0.5), terrain_look("rigid"));
  scene.add_obstacles(fixture::scattered_obstacles(15, 60.0, 2));
  scene.add_vehicle("ego", VehicleShape{});
  scene.add_vehicle("other", VehicleShape{});
  scene.set_vehicle_pose("ego", Pose{Vec3(0, 0, 1.0), Quat::Identity()}, {});
  scene.set_vehicle_pose("other", Pose{Vec3(10, 0, 1.0), Quat::Identity()}, {});
  scene.commit();
  LidarConfig cfg;  // VLP-16 on the roof, just above the chassis box
  cfg.mount.pose.position = Vec3(0, 0, 1.05);
  std::vector<std::vector<LidarPoint>> clouds;
  for (int threads : {1, 2}) {
    cfg.threads = threads;
    LidarSensor l(cfg, "ego", 5, kFrame);
    clouds.push_back(l.scan(scene, 3).points);
  }
  ASSERT_EQ(clouds[0].size(), clouds[1].size());
  for (std::size_t i = 0; i < clouds[0].size(); ++i) {
    EXPECT_EQ(std::memcmp(&clouds[0][i], &clouds[1][i], sizeof(LidarPoint)), 0);
  }
  // No return from inside the own chassis box; returns from the other vehicle 10 m ahead.
  int near = 0, other = 0;
  for (const auto& p : clouds[0]) {
    if (p.range < 2.5 && std::abs(p.x) < 2.4 && std::abs(p.y) < 1.1) ++near;
    if (std::abs(p.x - 10.0) < 2.4 && std::abs(p.y) < 1.1) ++other;
  }
  EXPECT_EQ(near, 0);
  EXPECT_GT(other, 20);
  cfg.hide_own_vehicle = false;
  LidarSensor sees_self(cfg, "ego", 5, kFrame);
  int self = 0;
  for (const auto& p : sees_self.scan(scene, 3).points) self += p.range < 2.5;
  EXPECT_GT(self, 100);  // downward channels hit the roof
}

TEST(LidarSensor, RateAndLagOnTheFrameGrid) {
  Scene scene;
  scene.add_obstacle(wall(20.0));
  scene.commit();
  LidarConfig cfg = front_lidar();  // 10 Hz, lag 0.1 s
  LidarSensor lidar(cfg, "", 1, kFrame);
  std::vector<std::pair<double, LidarScan>> seen;
  for (int f = 0; f <= 100; ++f) {
    const double t = f * kFrame;
    lidar.update(scene, t);
    for (auto& s : lidar.take_available(t)) seen.emplace_back(t, std::move(s));
  }
  ASSERT_EQ(seen.size(), 10u);
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_EQ(seen[k].second.stamp.sequence, k);
    EXPECT_NEAR(seen[k].second.stamp.time_s, 0.1 * static_cast<double>(k), 1e-12);
    EXPECT_NEAR(seen[k].first, seen[k].second.stamp.available_s, 1e-12);
    EXPECT_NEAR(seen[k].second.stamp.available_s - seen[k].second.stamp.time_s, 0.1, 1e-12);
  }
}

// The renderers trace 16-ray packets natively (AVX-512), as two 8-wide halves (AVX2) or ray by
// ray; every width this CPU offers meets what single rays meet. Embree's kernels may round
// differently where a ray grazes a triangle's edge, hence 99.9 % of the rays rather than all.
TEST(RayPackets, EveryWidthThisCpuTracesMeetsWhatSingleRaysMeet) {
  Scene scene;
  scene.set_terrain(fixture::rolling_terrain(60.0, 0.25, 0.5), terrain_look("rigid"));
  scene.add_obstacles(fixture::scattered_obstacles(15, 60.0, 2));
  scene.add_vehicle("other", VehicleShape{});
  scene.set_vehicle_pose("other", Pose{Vec3(10, 0, 1.0), Quat::Identity()}, {});
  scene.commit();
  const int native = native_width(scene.handle());
  std::vector<int> widths{8, 1};
  if (native == 16) widths.insert(widths.begin(), 16);
  if (native < 8) widths = {1};

  constexpr int kPackets = 256;  // 4096 rays fanned around the origin, down to the ground
  struct Traced {
    std::vector<unsigned> geom;
    std::vector<float> t;
    std::vector<float> shadow_tfar;
  };
  auto trace = [&](int width) {
    Traced out;
    HidingContext ctx;
    init_hiding_context(ctx, -1, true);
    for (int p = 0; p < kPackets; ++p) {
      alignas(64) RTCRayHit16 rh;
      alignas(64) RTCRay16 sr;
      alignas(64) int valid[16];
      for (int l = 0; l < 16; ++l) {
        valid[l] = (l % 5 == 4) ? 0 : -1;  // some lanes off, in both halves
        const double az = 2.0 * std::numbers::pi * (p * 16 + l) / (kPackets * 16.0);
        const double el = -0.05 - 0.3 * ((p * 16 + l) % 7) / 7.0;
        rh.ray.org_x[l] = sr.org_x[l] = 0.0f;
        rh.ray.org_y[l] = sr.org_y[l] = 0.0f;
        rh.ray.org_z[l] = sr.org_z[l] = 2.0f;
        rh.ray.dir_x[l] = sr.dir_x[l] = static_cast<float>(std::cos(el) * std::cos(az));
        rh.ray.dir_y[l] = sr.dir_y[l] = static_cast<float>(std::cos(el) * std::sin(az));
        rh.ray.dir_z[l] = sr.dir_z[l] = static_cast<float>(std::sin(el));
        rh.ray.tnear[l] = sr.tnear[l] = 0.0f;
        rh.ray.tfar[l] = sr.tfar[l] = 100.0f;
        rh.ray.time[l] = sr.time[l] = 0.0f;
        rh.ray.mask[l] = sr.mask[l] = 0xFFFFFFFFu;
        rh.ray.id[l] = sr.id[l] = static_cast<unsigned>(l);
        rh.ray.flags[l] = sr.flags[l] = 0;
        rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
      }
      intersect_at(width, valid, scene.handle(), &ctx.context, rh);
      occluded_at(width, valid, scene.handle(), &ctx.context, sr);
      for (int l = 0; l < 16; ++l) {
        if (!valid[l]) continue;
        out.geom.push_back(rh.hit.geomID[l]);
        out.t.push_back(rh.ray.tfar[l]);
        out.shadow_tfar.push_back(sr.tfar[l]);  // negative: occluded
      }
    }
    return out;
  };
  const Traced single = trace(1);
  std::size_t hits = 0;
  for (unsigned g : single.geom) hits += g != RTC_INVALID_GEOMETRY_ID;
  EXPECT_GT(hits, single.geom.size() / 2);
  for (int width : widths) {
    SCOPED_TRACE("width " + std::to_string(width));
    const Traced w = trace(width);
    ASSERT_EQ(w.geom.size(), single.geom.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < w.geom.size(); ++i) {
      const bool same = w.geom[i] == single.geom[i] &&
                        std::abs(w.t[i] - single.t[i]) <= 1e-3f &&
                        (w.shadow_tfar[i] < 0.0f) == (single.shadow_tfar[i] < 0.0f);
      differ += !same;
    }
    EXPECT_LE(differ, w.geom.size() / 1000) << differ << " of " << w.geom.size() << " rays";
  }
}
