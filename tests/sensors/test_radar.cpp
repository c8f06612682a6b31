// Radar (common/sensors/radar.hpp) against closed forms: range and angle of a box at known
// poses, radial speed = v . (p - s) / |p - s|, strength ~ r^-4 for a resolved target,
// clustering of vehicles side by side, the ground rule at a down-tilt, noise, determinism and
// checkpoint state.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/state_io.hpp"
#include "core/yaml.hpp"
#include "sensors/radar.hpp"
#include "sensors/random.hpp"
#include "sensors/rig_config.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {

constexpr double kFrame = 0.01;

// A box of half extents (depth, half_width, half_height) whose face towards the origin is
// centred at `face` and perpendicular to the horizontal line of sight.
world::Obstacle facing_box(const Vec3& face, double half_width = 1.0, double half_height = 1.0,
                           const std::string& label = "wall") {
  world::Obstacle o;
  o.id = "box";
  o.label = label;
  o.shape = world::ShapeKind::box;
  const double depth = 0.5;
  o.size = Vec3(depth, half_width, half_height);
  const Vec3 along = Vec3(face.x(), face.y(), 0.0).normalized();
  o.pose.position = face + depth * along;
  o.pose.orientation = Quat(Eigen::AngleAxisd(std::atan2(along.y(), along.x()), Vec3::UnitZ()));
  return o;
}

Pose fixed_pose(const Vec3& position, double pitch_down_deg = 0.0) {
  Pose p;
  p.position = position;
  p.orientation = Quat(Eigen::AngleAxisd(deg_to_rad(pitch_down_deg), Vec3::UnitY()));
  return p;
}

// A radar standing in the world at `pose` (no vehicle), no noise.
RadarConfig fixed_radar(const Pose& pose) {
  RadarConfig c;
  c.mount.pose = pose;
  return c;
}

void flat_ground(Scene& scene) {
  scene.set_terrain(TerrainGrid::flat(Vec2(-100, -100), 2.0, 151, 101, 0.0), terrain_look("rigid"));
}

Pose vehicle_at(double x, double y, double yaw_deg = 0.0) {
  Pose p;
  p.position = Vec3(x, y, 0.467);  // the HMMWV's wheel centres: its tyres touch z = 0
  p.orientation = Quat(Eigen::AngleAxisd(deg_to_rad(yaw_deg), Vec3::UnitZ()));
  return p;
}

Vec3 world_point(const RadarScan& s, const RadarDetection& d) {
  return s.pose.position + s.pose.orientation * Vec3(d.x, d.y, d.z);
}

double radial(const Vec3& v, const Vec3& target, const Vec3& sensor) {
  return v.dot((target - sensor).normalized());
}

}  // namespace

TEST(Radar, RaysSitAtTheCentresOfTheFieldOfViewCells) {
  RadarConfig c;  // 20 x 5 degrees, 200 x 50 rays
  const RadarSensor r(c, "", 1, kFrame);
  EXPECT_EQ(r.rays(), 10000);
  EXPECT_NEAR(r.azimuth_rad(0), deg_to_rad(-9.95), 1e-12);
  EXPECT_NEAR(r.azimuth_rad(199), deg_to_rad(9.95), 1e-12);
  EXPECT_NEAR(r.elevation_rad(0), deg_to_rad(-2.45), 1e-12);
  EXPECT_NEAR(r.elevation_rad(49), deg_to_rad(2.45), 1e-12);
  c.horizontal_rays = 4096;
  c.vertical_rays = 512;  // 2^21 rays: over the budget
  EXPECT_THROW(RadarSensor(c, "", 1, kFrame), std::invalid_argument);
}

// A box face-on at known poses (near, far, left, right, above): one detection at the face's
// centre, within a ray's spacing in angle and 2 cm in range.
TEST(Radar, ABoxGivesOneDetectionAtItsRangeAndAngle) {
  const Pose sensor = fixed_pose(Vec3(0, 0, 1));
  for (const Vec3& face : {Vec3(20, 0, 1), Vec3(25, 2, 1), Vec3(60, -5, 1.5), Vec3(100, 10, 2),
                           Vec3(140, -3, 1)}) {
    SCOPED_TRACE(face.transpose());
    Scene scene;
    scene.add_obstacle(facing_box(face));
    scene.commit();
    RadarSensor radar(fixed_radar(sensor), "", 1, kFrame);
    const RadarScan s = radar.scan(scene, 0);
    ASSERT_EQ(s.detections.size(), 1u);
    const RadarDetection& d = s.detections[0];
    const Vec3 rel = face - sensor.position;
    const double spacing = deg_to_rad(0.1);
    EXPECT_NEAR(d.range_m, rel.norm(), 0.02);
    EXPECT_NEAR(d.azimuth_rad, std::atan2(rel.y(), rel.x()), 0.5 * spacing);
    EXPECT_NEAR(d.elevation_rad, std::atan2(rel.z(), std::hypot(rel.x(), rel.y())), 0.5 * spacing);
    EXPECT_NEAR(d.radial_speed_mps, 0.0, 1e-6);
    EXPECT_GT(d.points, 10u);
  }
}

// A vehicle driving away, towards and across the beam, seen by a radar at rest: the radial speed
// is v . (p - s) / |p - s| at the detection's centroid p, within 0.05 m/s.
TEST(Radar, RadialSpeedIsTheVelocityAlongTheLineOfSight) {
  const Pose sensor = fixed_pose(Vec3(0, 0, 0.6));
  struct Case {
    const char* name;
    Pose pose;
    Vec3 velocity;
    double expected_sign;
  };
  const std::vector<Case> cases = {
      {"away", vehicle_at(30, 0), Vec3(6, 0, 0), +1.0},
      {"towards", vehicle_at(40, 3, 180), Vec3(-8, 0, 0), -1.0},
      {"crossing", vehicle_at(35, 4, 90), Vec3(0, 5, 0), +1.0},
      {"crossing_ahead", vehicle_at(35, 0, -90), Vec3(0, -5, 0), 0.0},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    Scene scene;
    flat_ground(scene);
    scene.add_vehicle("target", VehicleShape{});
    scene.set_vehicle_pose("target", c.pose, {});
    scene.set_vehicle_velocity("target", c.velocity, Vec3::Zero());
    scene.commit();
    RadarSensor radar(fixed_radar(sensor), "", 1, kFrame);
    const RadarScan s = radar.scan(scene, 0);
    ASSERT_EQ(s.detections.size(), 1u);
    const RadarDetection& d = s.detections[0];
    const double want = radial(c.velocity, world_point(s, d), sensor.position);
    EXPECT_NEAR(d.radial_speed_mps, want, 0.05);
    if (c.expected_sign > 0) {
      EXPECT_GT(want, 0.5);
    } else if (c.expected_sign < 0) {
      EXPECT_LT(want, -0.5);
    } else {
      EXPECT_NEAR(want, 0.0, 0.05);
    }
  }
}

// Mounted on a moving vehicle, the radar sees the world at rest closing at its own speed along
// each line of sight, and another vehicle at the difference of the two velocities.
TEST(Radar, OnAMovingVehicleTheWorldAtRestCloses) {
  Scene scene;
  flat_ground(scene);
  scene.add_vehicle("ego", VehicleShape{});
  scene.set_vehicle_pose("ego", vehicle_at(0, 0), {});
  scene.set_vehicle_velocity("ego", Vec3(7, 0, 0), Vec3::Zero());
  scene.add_vehicle("lead", VehicleShape{});
  scene.set_vehicle_pose("lead", vehicle_at(40, -2), {});
  scene.set_vehicle_velocity("lead", Vec3(5, 0, 0), Vec3::Zero());
  scene.add_obstacle(facing_box(Vec3(60, 6, 1.0), 1.5, 1.0, "rock"));
  scene.commit();
  RadarConfig c;
  c.mount.pose.position = Vec3(2.4, 0, 0.2);  // front bumper
  RadarSensor radar(c, "ego", 1, kFrame);
  const RadarScan s = radar.scan(scene, 0);
  EXPECT_NEAR((s.velocity - Vec3(7, 0, 0)).norm(), 0.0, 1e-9);
  ASSERT_EQ(s.detections.size(), 2u) << "the lead vehicle and the rock; the ego hidden";
  const RadarDetection& lead = s.detections[0];  // ordered by range
  const RadarDetection& rock = s.detections[1];
  EXPECT_NEAR(lead.radial_speed_mps,
              radial(Vec3(-2, 0, 0), world_point(s, lead), s.pose.position), 0.05);
  EXPECT_NEAR(rock.radial_speed_mps,
              radial(Vec3(-7, 0, 0), world_point(s, rock), s.pose.position), 0.05);
  EXPECT_LT(rock.radial_speed_mps, -6.5);
}

// A 2 m x 2 m plate resolved by the ray grid at 20 m and at 40 m: its strength falls by 2^4 = 16
// (within 1 %), its cross-section stays rho * area. The ray spacing puts the plate's edges
// between rays at both ranges, so both counts are exact (4 x as many rays at 20 m).
TEST(Radar, StrengthFallsWithTheFourthPowerOfRange) {
  const double step_deg = rad_to_deg(std::atan(1.0 / 40.0)) / 36.0;
  RadarConfig c = fixed_radar(fixed_pose(Vec3(0, 0, 2)));
  c.horizontal_rays = c.vertical_rays = 200;
  c.hfov_min_deg = c.vfov_min_deg = -100 * step_deg;
  c.hfov_max_deg = c.vfov_max_deg = 100 * step_deg;
  c.min_strength_db = -200;
  auto detect = [&](double range, const std::string& label) {
    Scene scene;
    scene.add_obstacle(facing_box(Vec3(range, 0, 2), 1.0, 1.0, label));
    scene.commit();
    RadarSensor radar(c, "", 1, kFrame);
    const RadarScan s = radar.scan(scene, 0);
    EXPECT_EQ(s.detections.size(), 1u);
    return s.detections.at(0);
  };
  const RadarDetection near = detect(20.0, "wall"), far = detect(40.0, "wall");
  EXPECT_EQ(near.points, 144u * 144u);
  EXPECT_EQ(far.points, 72u * 72u);
  const double ratio = std::pow(10.0, (near.strength_db - far.strength_db) / 10.0);
  EXPECT_NEAR(ratio, 16.0, 0.16);
  const double rho = c.reflectivity.of_obstacle("wall");
  EXPECT_NEAR(far.rcs_dbsm, 10.0 * std::log10(rho * 4.0), 0.05);
  EXPECT_NEAR(near.rcs_dbsm, far.rcs_dbsm, 0.05);
  EXPECT_NEAR(far.strength_db, far.rcs_dbsm - 40.0 * std::log10(far.range_m), 0.01);
  // Reflectivity by label: a tree sends back a third of what a rock does.
  const RadarDetection rock = detect(40.0, "rock"), tree = detect(40.0, "tree");
  EXPECT_NEAR(rock.strength_db - tree.strength_db, 10.0 * std::log10(0.3 / 0.1), 1e-3);
}

// Two HMMWVs side by side, 3 m apart (centre to centre, 0.84 m between their sides), at 30 m:
// two detections; one alone: one.
TEST(Radar, VehiclesSideBySideAreSeparateDetections) {
  const Pose sensor = fixed_pose(Vec3(0, 0, 0.6));
  for (const bool both : {true, false}) {
    SCOPED_TRACE(both ? "two" : "one");
    Scene scene;
    flat_ground(scene);
    scene.add_vehicle("left", VehicleShape{});
    scene.set_vehicle_pose("left", vehicle_at(30, 1.5), {});
    if (both) {
      scene.add_vehicle("right", VehicleShape{});
      scene.set_vehicle_pose("right", vehicle_at(30, -1.5), {});
    }
    scene.commit();
    RadarSensor radar(fixed_radar(sensor), "", 1, kFrame);
    const RadarScan s = radar.scan(scene, 0);
    ASSERT_EQ(s.detections.size(), both ? 2u : 1u);
    std::vector<double> az;
    for (const auto& d : s.detections) {
      az.push_back(d.azimuth_rad);
      EXPECT_NEAR(d.range_m, 30.0 - 2.35, 0.6);  // the rear of the body
    }
    std::sort(az.begin(), az.end());
    EXPECT_NEAR(az.back(), std::atan2(1.5, 30.0 - 2.35), 0.01);
    if (both) {
      EXPECT_NEAR(az.front(), std::atan2(-1.5, 30.0 - 2.35), 0.01);
    }
  }
}

// Tilted 5 degrees down from 1 m, the beam meets flat ground between 1/sin(7.5 deg) and
// 1/sin(2.5 deg). ground: remove drops those returns (nothing is detected); ground: keep
// reports them, every detection within that band. A vehicle moving on that ground stays apart
// from it in both (its Doppler: the ground is at rest).
TEST(Radar, GroundAtADownTiltIsRemovedOrKeptAsConfigured) {
  const Pose sensor = fixed_pose(Vec3(0, 0, 1.0), 5.0);
  for (const bool keep : {false, true}) {
    for (const bool vehicle : {false, true}) {
      SCOPED_TRACE(std::string(keep ? "keep" : "remove") + (vehicle ? ", vehicle" : ""));
      Scene scene;
      flat_ground(scene);
      if (vehicle) {
        scene.add_vehicle("target", VehicleShape{});
        scene.set_vehicle_pose("target", vehicle_at(16, 0), {});
        scene.set_vehicle_velocity("target", Vec3(4, 0, 0), Vec3::Zero());
      }
      scene.commit();
      RadarConfig c = fixed_radar(sensor);
      c.ground = keep ? RadarGround::keep : RadarGround::remove;
      c.min_strength_db = -200;
      RadarSensor radar(c, "", 1, kFrame);
      const RadarScan s = radar.scan(scene, 0);
      std::size_t moving = 0, ground = 0;
      for (const auto& d : s.detections) {
        const Vec3 p = world_point(s, d);
        if (std::abs(d.radial_speed_mps) > 3.0) {
          ++moving;  // its wheels and what the beam meets under its body
          EXPECT_NEAR(p.x(), 16.0, 2.4);
          EXPECT_NEAR(d.radial_speed_mps, radial(Vec3(4, 0, 0), p, sensor.position), 0.05);
          continue;
        }
        ++ground;
        EXPECT_NEAR(p.z(), 0.0, 1e-3);
        EXPECT_GE(d.range_m, 1.0 / std::sin(deg_to_rad(7.5)) - 0.1);
        EXPECT_LE(d.range_m, 1.0 / std::sin(deg_to_rad(2.5)) + 0.1);
      }
      EXPECT_EQ(moving > 0, vehicle);
      if (keep) {
        EXPECT_GE(ground, 1u);
      } else {
        EXPECT_EQ(ground, 0u);
      }
    }
  }
}

// Noise: a pure function of (seed, scan, detection) with the configured standard deviations;
// the thread count changes nothing.
TEST(Radar, NoiseHasTheConfiguredSpreadAndThreadsChangeNothing) {
  Scene scene;
  flat_ground(scene);
  scene.add_vehicle("target", VehicleShape{});
  scene.set_vehicle_pose("target", vehicle_at(30, 2), {});
  scene.set_vehicle_velocity("target", Vec3(3, 0, 0), Vec3::Zero());
  scene.add_obstacle(facing_box(Vec3(50, -5, 1.0), 1.0, 1.0, "rock"));
  scene.commit();
  RadarConfig c = fixed_radar(fixed_pose(Vec3(0, 0, 0.6)));
  c.range_noise_std_m = 0.2;
  c.azimuth_noise_std_rad = 0.003;
  c.elevation_noise_std_rad = 0.002;
  c.speed_noise_std_mps = 0.1;
  RadarConfig noiseless = c;
  noiseless.range_noise_std_m = noiseless.azimuth_noise_std_rad = 0;
  noiseless.elevation_noise_std_rad = noiseless.speed_noise_std_mps = 0;
  RadarSensor truth(noiseless, "", 7, kFrame);
  const RadarScan t = truth.scan(scene, 0);
  ASSERT_EQ(t.detections.size(), 2u);
  RadarSensor one(c, "", 7, kFrame);
  c.threads = 2;
  RadarSensor two(c, "", 7, kFrame);
  std::vector<double> dr, da, de, dv;
  for (std::uint64_t k = 0; k < 300; ++k) {
    const RadarScan a = one.scan(scene, k), b = two.scan(scene, k);
    ASSERT_EQ(a.detections.size(), 2u);
    ASSERT_EQ(b.detections.size(), 2u);
    core::StateWriter wa, wb;
    wa.io(a);
    wb.io(b);
    ASSERT_EQ(wa.bytes(), wb.bytes()) << "scan " << k;
    for (std::size_t i = 0; i < 2; ++i) {
      dr.push_back(a.detections[i].range_m - t.detections[i].range_m);
      da.push_back(a.detections[i].azimuth_rad - t.detections[i].azimuth_rad);
      de.push_back(a.detections[i].elevation_rad - t.detections[i].elevation_rad);
      dv.push_back(a.detections[i].radial_speed_mps - t.detections[i].radial_speed_mps);
    }
  }
  auto check = [](const std::vector<double>& v, double sigma) {
    double mean = 0, var = 0;
    for (double x : v) mean += x;
    mean /= static_cast<double>(v.size());
    for (double x : v) var += (x - mean) * (x - mean);
    const double sd = std::sqrt(var / static_cast<double>(v.size() - 1));
    EXPECT_NEAR(sd, sigma, 0.1 * sigma);
    EXPECT_NEAR(mean, 0.0, 4.0 * sigma / std::sqrt(static_cast<double>(v.size())));
  };
  check(dr, 0.2);
  check(da, 0.003);
  check(de, 0.002);
  check(dv, 0.1);
  // Another seed, another draw.
  RadarSensor other(c, "", 8, kFrame);
  EXPECT_NE(other.scan(scene, 0).detections[0].range_m, one.scan(scene, 0).detections[0].range_m);
}

// A radar restored from a checkpoint taken while scans wait for their lag continues exactly as
// the one that was not interrupted; a state of another seed is refused by name.
TEST(Radar, StateRestoresTheScheduleAndTheWaitingScans) {
  Scene scene;
  flat_ground(scene);
  scene.add_vehicle("target", VehicleShape{});
  scene.set_vehicle_velocity("target", Vec3(2, 0, 0), Vec3::Zero());
  RadarConfig c = fixed_radar(fixed_pose(Vec3(0, 0, 0.6)));
  c.rate_hz = 20;
  c.lag_s = 0.12;
  c.range_noise_std_m = 0.1;
  auto pose_at = [&](int k) {
    scene.set_vehicle_pose("target", vehicle_at(20 + 0.02 * k, 0), {});
    scene.commit();
  };
  RadarSensor a(c, "", 3, kFrame);
  std::vector<std::string> want, got;
  auto take = [](RadarSensor& r, double t, std::vector<std::string>& out) {
    for (const auto& s : r.take_available(t)) {
      core::StateWriter w;
      w.io(s);
      out.push_back(w.bytes());
    }
  };
  core::StateWriter saved;
  for (int k = 0; k < 60; ++k) {
    pose_at(k);
    a.update(scene, k * kFrame);
    take(a, k * kFrame, want);
    if (k == 30) a.save_state(saved);
  }
  RadarSensor b(c, "", 3, kFrame);
  core::StateReader r(saved.bytes(), "test");
  b.load_state(r);
  for (int k = 31; k < 60; ++k) {
    pose_at(k);
    b.update(scene, k * kFrame);
    take(b, k * kFrame, got);
  }
  ASSERT_GE(want.size(), got.size());
  ASSERT_GT(got.size(), 5u);
  EXPECT_EQ(std::vector<std::string>(want.end() - static_cast<std::ptrdiff_t>(got.size()), want.end()),
            got);
  RadarSensor other(c, "", 4, kFrame);
  core::StateReader r2(saved.bytes(), "test");
  try {
    other.load_state(r2);
    FAIL() << "a state of another seed was accepted";
  } catch (const core::StateError& e) {
    EXPECT_NE(std::string(e.what()).find("radar with another noise seed"), std::string::npos);
  }
}

TEST(Radar, RigFilesAreReadStrictly) {
  const std::string rig = R"(name: r
sensors:
  - id: front_radar
    type: radar
    rate_hz: 20
    lag_s: 0.05
    mount: {position_m: [2.45, 0, 0.6]}
    hfov_deg: [-10, 10]
    vfov_deg: [-2.5, 2.5]
    rays: [200, 50]
    range_m: [0.5, 150]
    cluster: {range_gate_m: 1.5, speed_gate_mps: 0.5, min_points: 2}
    min_strength_db: -95
    max_detections: 64
    ground: keep
    reflectivity: {vehicle: 2.0, rock: 0.4, fence: 0.6}
    noise: {range_std_m: 0.1, azimuth_std_rad: 0.002, elevation_std_rad: 0.003, speed_std_mps: 0.05}
    threads: 2
)";
  const SensorRig r = parse_sensor_rig(YamlNode::load_string(rig, "rig.yaml"));
  ASSERT_EQ(r.radars.size(), 1u);
  EXPECT_TRUE(r.has_rendered_sensors());
  const RadarConfig& c = r.radars[0];
  EXPECT_EQ(c.horizontal_rays, 200);
  EXPECT_EQ(c.vertical_rays, 50);
  EXPECT_EQ(c.min_points, 2);
  EXPECT_EQ(c.max_detections, 64);
  EXPECT_EQ(c.ground, RadarGround::keep);
  EXPECT_DOUBLE_EQ(c.reflectivity.vehicle, 2.0);
  EXPECT_DOUBLE_EQ(c.reflectivity.of_obstacle("rock"), 0.4);
  EXPECT_DOUBLE_EQ(c.reflectivity.of_obstacle("fence"), 0.6);
  EXPECT_DOUBLE_EQ(c.reflectivity.of_obstacle("tree"), 0.1);  // default kept
  EXPECT_DOUBLE_EQ(c.elevation_noise_std_rad, 0.003);
  EXPECT_DOUBLE_EQ(c.mount.pose.position.x(), 2.45);
  auto error = [&](const std::string& from, const std::string& to) {
    std::string bad = rig;
    bad.replace(bad.find(from), from.size(), to);
    try {
      parse_sensor_rig(YamlNode::load_string(bad, "rig.yaml"));
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(error("ground: keep", "ground: sometimes").find("rig.yaml:15"), std::string::npos);
  EXPECT_NE(error("min_points: 2", "min_pts: 2").find("min_pts"), std::string::npos);
  EXPECT_NE(error("rays: [200, 50]", "rays: [4096, 1024]").find("budget"), std::string::npos);
  EXPECT_NE(error("rays: [200, 50]", "rays: [200.5, 50]").find("whole numbers"), std::string::npos);
  EXPECT_NE(error("rock: 0.4", "rock: -1").find("rock"), std::string::npos);
  EXPECT_NE(error("range_m: [0.5, 150]", "range_m: [150, 0.5]").find("min <= max"),
            std::string::npos);
}
