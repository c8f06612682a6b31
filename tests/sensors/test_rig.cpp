#include <gtest/gtest.h>

#include <functional>

#include "sensors/rig.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {
std::string rig_file(const std::string& name) {
  return sensor_rig_path(name, SYNDDS_TEST_CONFIG_DIR);
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

SensorRig parse(const std::string& text) {
  return parse_sensor_rig(YamlNode::load_string(text, "rig.yaml"));
}
}  // namespace

TEST(SensorRig, DefaultRigHasThePapersSensors) {
  const SensorRig rig = load_sensor_rig(rig_file("default"));
  EXPECT_EQ(rig.name, "default");
  ASSERT_EQ(rig.cameras.size(), 1u);
  const auto& cam = rig.cameras[0];
  EXPECT_EQ(cam.intrinsics.width, 80);
  EXPECT_EQ(cam.intrinsics.height, 45);
  EXPECT_DOUBLE_EQ(cam.rate_hz, 30.0);
  EXPECT_DOUBLE_EQ(cam.lag_s, 0.05);
  EXPECT_DOUBLE_EQ(cam.exposure_s, 0.02);
  EXPECT_EQ(cam.mode, CameraMode::mounted);
  EXPECT_NEAR((cam.mount.pose.orientation * Vec3::UnitX()).z(), -std::sin(deg_to_rad(5.0)), 1e-12);
  ASSERT_EQ(rig.lidars.size(), 1u);
  EXPECT_EQ(rig.lidars[0].channels, 16);
  EXPECT_EQ(rig.lidars[0].samples, 900);
  EXPECT_DOUBLE_EQ(rig.lidars[0].range_noise_std_m, 0.01);
  ASSERT_EQ(rig.gps.size(), 1u);
  EXPECT_DOUBLE_EQ(rig.gps[0].rate_hz, 10.0);
  EXPECT_DOUBLE_EQ(rig.gps[0].lag_s, 0.1);
  ASSERT_EQ(rig.imus.size(), 1u);
  EXPECT_DOUBLE_EQ(rig.imus[0].rate_hz, 100.0);
  // Noise density times sqrt(rate) (docs/sources.md, ADIS16448-class).
  EXPECT_NEAR(rig.imus[0].accelerometer.white_std.x(), 4e-3 * 10.0, 1e-15);
  EXPECT_NEAR(rig.imus[0].gyroscope.white_std.z(), 3.4e-4 * 10.0, 1e-15);
  EXPECT_EQ(rig.magnetometers.size(), 1u);
  EXPECT_EQ(rig.tachometers.size(), 1u);
  EXPECT_EQ(rig.sensor_ids.size(), 6u);
  EXPECT_NEAR(rig.geodetic_origin.lat_deg, 43.070, 1e-12);

  const SensorRig chase = load_sensor_rig(rig_file("chase"));
  ASSERT_EQ(chase.cameras.size(), 1u);
  EXPECT_EQ(chase.cameras[0].mode, CameraMode::chase);
  EXPECT_EQ(chase.cameras[0].noise, PixelNoiseModel::none);
  EXPECT_EQ(chase.cameras[0].chase.azimuth_deg, 0.0);  // straight behind unless given
  const SensorRig swung = parse(
      "name: r\nsensors:\n  - {id: c, type: camera, mode: chase, chase: {azimuth_deg: -35}}\n");
  EXPECT_EQ(swung.cameras[0].chase.azimuth_deg, -35.0);
  EXPECT_EQ(swung.cameras[0].chase.distance_m, ChaseConfig{}.distance_m);
}

TEST(SensorRig, ErrorsNameFileLineAndKey) {
  const std::string unknown = error_of(
      [] { parse("name: r\nsensors:\n  - id: cam\n    type: camera\n    widht_px: 80\n"); });
  EXPECT_NE(unknown.find("rig.yaml:5:5"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("unknown key 'widht_px'"), std::string::npos) << unknown;

  const std::string nested = error_of([] {
    parse(
        "name: r\nsensors:\n  - id: l\n    type: lidar\n    beam: {divergence_rad: 0.003, "
        "retrun: mean}\n");
  });
  EXPECT_NE(nested.find("rig.yaml:5:"), std::string::npos) << nested;
  EXPECT_NE(nested.find("retrun"), std::string::npos) << nested;

  const std::string dup = error_of(
      [] { parse("name: r\nsensors:\n  - {id: a, type: gps}\n  - {id: a, type: imu}\n"); });
  EXPECT_NE(dup.find("rig.yaml:4:"), std::string::npos) << dup;
  EXPECT_NE(dup.find("duplicate sensor id 'a'"), std::string::npos) << dup;

  const std::string type = error_of([] { parse("name: r\nsensors:\n  - {id: a, type: sonar}\n"); });
  EXPECT_NE(type.find("must be one of"), std::string::npos) << type;

  const std::string range = error_of(
      [] { parse("name: r\nsensors:\n  - id: c\n    type: camera\n    width_px: 8000\n"); });
  EXPECT_NE(range.find("rig.yaml:5:15: sensors[0].width_px"), std::string::npos) << range;

  const std::string both = error_of([] {
    parse(
        "name: r\nsensors:\n  - id: i\n    type: imu\n    gyroscope: {std: 0.1, "
        "density_per_sqrt_hz: 0.01}\n");
  });
  EXPECT_NE(both.find("not both"), std::string::npos) << both;

  const std::string fold = error_of([] {
    parse("name: r\nsensors:\n  - id: c\n    type: camera\n    distortion: {k1: -0.9}\n");
  });
  EXPECT_NE(fold.find("rig.yaml:3:"), std::string::npos) << fold;
  EXPECT_NE(fold.find("folds"), std::string::npos) << fold;

  const std::string azimuth = error_of([] {
    parse(
        "name: r\nsensors:\n  - id: c\n    type: camera\n    mode: chase\n"
        "    chase: {distance_m: 9, azimuth_deg: 200}\n");
  });
  EXPECT_NE(azimuth.find("rig.yaml:6:"), std::string::npos) << azimuth;
  EXPECT_NE(azimuth.find("sensors[0].chase.azimuth_deg"), std::string::npos) << azimuth;

  const std::string missing = error_of([] { parse("name: r\n"); });
  EXPECT_NE(missing.find("missing required key 'sensors'"), std::string::npos) << missing;
}

TEST(VehicleSensors, DefaultRigRunsOneSecondWithRatesAndLags) {
  const SensorRig rig = load_sensor_rig(rig_file("default"));
  Scene scene(rig.scene);
  scene.set_terrain(TerrainGrid::flat(Vec2(-50, -50), 0.5, 201, 201, 0.0), terrain_look("rigid"));
  scene.add_vehicle("lead", VehicleShape{});
  VehicleSensors sensors(rig, "lead", 42, 0.002, 0.01);
  InteroceptiveBatch intero;
  RenderedBatch rendered;
  for (int frame = 0; frame <= 100; ++frame) {
    // Dynamics steps of the frame (5 x 2 ms), then the frame's rendering.
    for (int step = 0; step < 5 && (frame < 100 || step == 0); ++step) {
      vehicle::VehicleSnapshot s;
      s.time_s = frame * 0.01 + step * 0.002;
      s.pose.position = Vec3(5.0 * s.time_s, 0.0, 0.467);
      s.linear_velocity = Vec3(5.0, 0.0, 0.0);
      s.wheels.resize(4);
      for (auto& w : s.wheels) w.spin_rad_s = 5.0 / 0.467;
      sensors.update_dynamics(s);
      if (step == 0) {
        scene.set_vehicle_pose("lead", s);
        scene.commit();
        sensors.update_rendered(scene, s.time_s);
      }
      const double now = s.time_s;
      auto i = sensors.take_interoceptive(now);
      for (auto& g : i.gps) intero.gps.push_back(g);
      for (auto& g : i.imu) intero.imu.push_back(g);
      for (auto& g : i.magnetometer) intero.magnetometer.push_back(g);
      for (auto& g : i.tachometer) intero.tachometer.push_back(g);
      auto r = sensors.take_rendered(now);
      for (auto& c : r.camera) rendered.camera.push_back(std::move(c));
      for (auto& l : r.lidar) rendered.lidar.push_back(std::move(l));
    }
  }
  EXPECT_EQ(intero.gps.size(), 10u);   // measured 0.0 .. 0.9, lag 0.1
  EXPECT_EQ(intero.imu.size(), 101u);  // 0.00 .. 1.00, no lag
  EXPECT_EQ(intero.magnetometer.size(), 51u);
  EXPECT_EQ(intero.tachometer.size(), 101u);
  EXPECT_EQ(rendered.camera.size(), 29u);  // 30 Hz, the 30th still within its 0.05 s lag
  EXPECT_EQ(rendered.lidar.size(), 10u);
  for (const auto& g : intero.gps) {
    EXPECT_NEAR(g.stamp.available_s - g.stamp.time_s, 0.1, 1e-12);
    EXPECT_NEAR(g.true_enu_m.x(), 5.0 * g.stamp.time_s, 1e-9);
  }
  for (const auto& t : intero.tachometer) EXPECT_NEAR(t.wheel_spin_rad_s[0], 5.0 / 0.467, 0.3);
  EXPECT_EQ(rendered.camera[0].image.width, 80);
  EXPECT_EQ(rendered.lidar[0].channels, 16);
  EXPECT_GT(rendered.lidar[0].points.size(), 5000u);  // the ground all around
}

TEST(VehicleSensors, SeedsPerVehicleAndSensorAndTimeGridErrors) {
  SensorRig rig = parse("name: r\nsensors:\n  - {id: imu, type: imu, accelerometer: {std: 0.1}}\n");
  rig.file = "r.yaml";
  auto run = [&](const std::string& vehicle) {
    VehicleSensors s(rig, vehicle, 7, 0.002, 0.01);
    std::vector<double> out;
    for (int i = 0; i < 50; ++i) {
      vehicle::VehicleSnapshot snap;
      snap.time_s = i * 0.002;
      s.update_dynamics(snap);
      for (const auto& m : s.take_interoceptive(snap.time_s).imu) out.push_back(m.accel_mps2.x());
    }
    return out;
  };
  EXPECT_EQ(run("a"), run("a"));
  EXPECT_NE(run("a"), run("b"));

  SensorRig fast = parse("name: r\nsensors:\n  - {id: cam, type: camera, rate_hz: 200}\n");
  fast.file = "fast.yaml";
  const std::string err = error_of([&] { VehicleSensors(fast, "a", 1, 0.002, 0.01); });
  EXPECT_NE(err.find("fast.yaml: sensor 'cam' on vehicle 'a'"), std::string::npos) << err;
}
