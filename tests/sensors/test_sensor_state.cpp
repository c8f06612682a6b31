// Checkpoints of a vehicle's sensors and its V2V broadcaster: saved at a frame boundary and
// loaded into freshly built ones, they continue with every sample (values and stamps)
// bit-identical to those that ran on: random streams with a spare Box-Muller variate, bias
// walks, samples waiting for their lag, a camera exposure left open across frames, lidar scans
// in flight, V2V drops and latency.
#include <gtest/gtest.h>

#include "../core/state_test_util.hpp"

#include <cmath>
#include <string>
#include <vector>

#include "convoy/v2v.hpp"
#include "core/state_io.hpp"
#include "scene_fixture.hpp"
#include "sensors/rig.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {

constexpr double kStep = 2e-3;

SensorRig default_rig() {
  return load_sensor_rig(sensor_rig_path("default", SYNDDS_TEST_CONFIG_DIR));
}

/// The vehicle at step n: a curving, accelerating path; three wheels, so the tachometer draws
/// an odd number of normals per sample and its stream often holds a spare variate.
vehicle::VehicleSnapshot snapshot_at(std::int64_t n, double step_s = kStep) {
  vehicle::VehicleSnapshot s;
  const double t = static_cast<double>(n) * step_s;
  s.time_s = t;
  s.pose.position = Vec3(3.0 * t + 0.2 * t * t, 2.0 * std::sin(0.3 * t), 0.5);
  s.pose.orientation = quat_from_yaw(0.3 * std::cos(0.3 * t));
  s.linear_velocity = Vec3(3.0 + 0.4 * t, 0.6 * std::cos(0.3 * t), 0.0);
  s.angular_velocity = Vec3(0.01, -0.02, -0.09 * std::sin(0.3 * t));
  s.linear_acceleration = Vec3(0.4, -0.18 * std::sin(0.3 * t), 0.05 * std::sin(7.0 * t));
  s.angular_acceleration = Vec3(0.0, 0.0, -0.027 * std::cos(0.3 * t));
  for (int w = 0; w < 3; ++w) {
    vehicle::WheelSnapshot ws;
    ws.spin_rad_s = (3.0 + 0.4 * t) / 0.467 + 0.01 * w;
    s.wheels.push_back(ws);
  }
  return s;
}

/// Every sample of a batch, exactly (the checkpoint's own encoding is bit-exact).
void append(core::StateWriter& trace, const InteroceptiveBatch& b) {
  for (const auto& s : b.gps) save_sample(trace, s);
  for (const auto& s : b.imu) save_sample(trace, s);
  for (const auto& s : b.magnetometer) save_sample(trace, s);
  for (const auto& s : b.tachometer) save_sample(trace, s);
}

void append(core::StateWriter& trace, const std::vector<proto::V2VMessageMsg>& messages) {
  for (const auto& m : messages) {
    trace.io(m.vehicle_id);
    trace.io(m.frame);
    trace.io(m.sequence);
    trace.io(m.sensor_time_s);
    trace.io(m.latitude_deg);
    trace.io(m.longitude_deg);
    trace.io(m.altitude_m);
    trace.io(m.speed_mps);
    trace.io(m.heading_rad);
  }
}

void append(core::StateWriter& trace, const RenderedBatch& b) {
  for (const auto& f : b.camera) {
    trace.io(f.sensor_id);
    trace.io(f.stamp);
    trace.io(f.pose.position);
    trace.io(f.pose.orientation);
    trace.io(f.image.pixels);
  }
  for (const auto& s : b.lidar) {
    trace.io(s.sensor_id);
    trace.io(s.stamp);
    trace.io(s.pose.position);
    trace.io(static_cast<std::uint64_t>(s.points.size()));
    for (const auto& p : s.points) {
      trace.io(p.x);
      trace.io(p.y);
      trace.io(p.z);
      trace.io(p.intensity);
      trace.io(p.range);
      trace.io(p.channel);
      trace.io(p.sample);
    }
  }
}

template <typename T>
std::string save(const T& x) {
  core::StateWriter w;
  x.save_state(w);
  return w.take();
}

template <typename T>
void load(T& x, const std::string& bytes) {
  core::StateReader r(bytes, "sensors.state");
  x.load_state(r);
  EXPECT_TRUE(r.at_end());
}

/// A vehicle process's interoceptive sensors and V2V, frame by frame as the vehicle agent
/// runs them (frames of `steps_per_frame` dynamics steps).
struct InteroceptiveRun {
  static constexpr int kStepsPerFrame = 5;
  static constexpr double kFrame = kStepsPerFrame * kStep;
  VehicleSensors sensors{default_rig(), "ego", 42, kStep, kFrame, SensorSet::interoceptive};
  convoy::V2VBroadcaster v2v{convoy::V2VConfig{20.0, 0.03, 0.3}, "ego", "vehicle/ego", 0.467, 42};
  std::int64_t frame = 0;

  void run_frame(core::StateWriter& samples, core::StateWriter& messages) {
    if (frame > 0) {
      for (int s = 1; s <= kStepsPerFrame; ++s) {
        sensors.update_dynamics(snapshot_at((frame - 1) * kStepsPerFrame + s));
      }
    } else {
      sensors.update_dynamics(snapshot_at(0));
    }
    const double now = static_cast<double>(frame) * kFrame;
    const InteroceptiveBatch batch = sensors.take_interoceptive(now);
    append(samples, batch);
    v2v.observe(batch);
    append(messages, v2v.step(frame, now));
    ++frame;
  }
};

}  // namespace

TEST(SensorState, InteroceptiveSensorsResumeBitForBit) {
  InteroceptiveRun a;
  core::StateWriter ignored;
  for (int f = 0; f < 31; ++f) a.run_frame(ignored, ignored);
  // GPS samples wait 0.1 s (10 frames) for their lag: the checkpoint must carry them.
  ASSERT_GT(a.sensors.gps()[0].pending(), 0u);

  InteroceptiveRun b;
  load(b.sensors, save(a.sensors));
  load(b.v2v, save(a.v2v));
  b.frame = a.frame;
  EXPECT_EQ(save(b.sensors), save(a.sensors));

  core::StateWriter sa, sb, ma, mb;
  for (int f = 0; f < 150; ++f) {
    a.run_frame(sa, ma);
    b.run_frame(sb, mb);
  }
  EXPECT_GT(sa.bytes().size(), 10000u);
  EXPECT_TRUE(sa.bytes() == sb.bytes()) << "samples differ after the checkpoint";
  EXPECT_EQ(save(a.sensors), save(b.sensors));
}

TEST(SensorState, V2VResumesBitForBit) {
  InteroceptiveRun a;
  core::StateWriter ignored;
  // Save with a message waiting for its latency (built at a frame end, released 3 frames on).
  while (a.frame < 30 || a.v2v.pending() == 0) a.run_frame(ignored, ignored);
  ASSERT_LT(a.frame, 100);
  ASSERT_GT(a.v2v.dropped(), 0u);

  InteroceptiveRun b;
  load(b.sensors, save(a.sensors));
  load(b.v2v, save(a.v2v));
  b.frame = a.frame;
  EXPECT_EQ(save(b.v2v), save(a.v2v));

  core::StateWriter sa, sb, ma, mb;
  for (int f = 0; f < 200; ++f) {
    a.run_frame(sa, ma);
    b.run_frame(sb, mb);
  }
  EXPECT_GT(ma.bytes().size(), 1000u);
  EXPECT_TRUE(ma.bytes() == mb.bytes()) << "messages differ after the checkpoint";
  EXPECT_EQ(a.v2v.dropped(), b.v2v.dropped());
  EXPECT_EQ(a.v2v.built(), b.v2v.built());
  EXPECT_EQ(save(a.v2v), save(b.v2v));
}

// The sensor process: camera (an averaged exposure over four frames, so a capture is open at
// most frame ends) and lidar (scans wait a turn for their lag) on a moving vehicle.
TEST(SensorState, RenderedSensorsResumeBitForBit) {
  constexpr double kFrame = 0.005;
  SensorRig rig = default_rig();
  ASSERT_EQ(rig.cameras.size(), 1u);
  rig.cameras[0].exposure_mode = ExposureMode::average;
  rig.cameras[0].subframes = 4;
  rig.cameras[0].exposure_s = 0.02;
  Scene scene;
  scene.set_terrain(fixture::rolling_terrain(60.0, 0.25, 0.5), terrain_look("rigid"));
  scene.add_obstacles(fixture::scattered_obstacles(15, 60.0, 2));
  scene.add_vehicle("ego", VehicleShape{});
  scene.add_vehicle("other", VehicleShape{});
  auto pose_world = [&](std::int64_t frame) {
    const vehicle::VehicleSnapshot s = snapshot_at(frame, kFrame);
    scene.set_vehicle_pose("ego", s.pose, {});
    scene.set_vehicle_pose("other", Pose{s.pose.position + Vec3(12, 1, 0), Quat::Identity()}, {});
    scene.commit();
  };
  VehicleSensors a(rig, "ego", 42, 1e-3, kFrame, SensorSet::rendered);
  core::StateWriter ignored;
  std::int64_t frame = 0;
  // Camera triggers at ticks 0, 7, 14, 20, ...; after tick 21 the capture of tick 20 holds one
  // of its four renders.
  for (; frame <= 21; ++frame) {
    pose_world(frame);
    a.update_rendered(scene, static_cast<double>(frame) * kFrame);
    append(ignored, a.take_rendered(static_cast<double>(frame) * kFrame));
  }
  const std::size_t renders_at_save = a.cameras()[0]->renders();

  VehicleSensors b(rig, "ego", 42, 1e-3, kFrame, SensorSet::rendered);
  load(b, save(a));
  EXPECT_EQ(b.cameras()[0]->renders(), renders_at_save);
  EXPECT_EQ(save(b), save(a));

  core::StateWriter ta, tb;
  std::size_t frames = 0, scans = 0;
  for (; frame < 120; ++frame) {
    pose_world(frame);
    const double t = static_cast<double>(frame) * kFrame;
    a.update_rendered(scene, t);
    b.update_rendered(scene, t);
    const RenderedBatch ba = a.take_rendered(t);
    frames += ba.camera.size();
    scans += ba.lidar.size();
    append(ta, ba);
    append(tb, b.take_rendered(t));
  }
  EXPECT_GT(frames, 10u);
  EXPECT_GT(scans, 3u);
  EXPECT_TRUE(ta.bytes() == tb.bytes()) << "frames or scans differ after the checkpoint";
  EXPECT_EQ(a.cameras()[0]->renders(), b.cameras()[0]->renders());
  EXPECT_EQ(save(a), save(b));
}

TEST(SensorState, AStateOfAnotherVehicleOrRigIsRefused) {
  InteroceptiveRun a;
  core::StateWriter ignored;
  for (int f = 0; f < 5; ++f) a.run_frame(ignored, ignored);
  const std::string bytes = save(a.sensors);
  {
    VehicleSensors other(default_rig(), "other", 42, kStep, InteroceptiveRun::kFrame,
                         SensorSet::interoceptive);
    syndds::test::expect_state_error([&] { load(other, bytes); },
                       {"sensors.state", "vehicle_sensors", "vehicle 'ego', not 'other'"});
  }
  {
    SensorRig rig = default_rig();
    rig.gps[0].rate_hz = 20.0;
    VehicleSensors other(rig, "ego", 42, kStep, InteroceptiveRun::kFrame, SensorSet::interoceptive);
    syndds::test::expect_state_error([&] { load(other, bytes); },
                       {"section 'gps'", "sensor 'gps' ran on another schedule"});
  }
  {
    SensorRig rig = default_rig();
    rig.imus.clear();
    VehicleSensors other(rig, "ego", 42, kStep, InteroceptiveRun::kFrame, SensorSet::interoceptive);
    syndds::test::expect_state_error([&] { load(other, bytes); }, {"the state has 1 imu sensors, this rig 0"});
  }
  {
    VehicleSensors fresh(default_rig(), "ego", 42, kStep, InteroceptiveRun::kFrame,
                         SensorSet::interoceptive);
    syndds::test::expect_state_error([&] { load(fresh, bytes.substr(0, bytes.size() - 3)); },
                       {"sensors.state", "section 'vehicle_sensors' claims"});
  }
  {
    convoy::V2VBroadcaster other({10.0, 0.03, 0.3}, "ego", "vehicle/ego", 0.467, 42);
    syndds::test::expect_state_error([&] { load(other, save(a.v2v)); }, {"section 'v2v'", "(rate_hz 20, latency_s 0.03, drop_probability 0.3)",
                        "this one's (rate_hz 10,"});
  }
}
