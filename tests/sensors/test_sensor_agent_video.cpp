// A sensor member whose camera writes a video takes part in checkpoints: rolled back in the
// same process, or restarted (a new agent on the run directory) and restored, it ends with the
// video and frames.csv of a run that never stopped, byte for byte; a video begun after the
// checkpoint is removed on the rollback.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "agents/agent_factory.hpp"
#include "agents/sensor_agent.hpp"
#include "core/state_io.hpp"
#include "scenario/scenario.hpp"

using namespace syndds;

namespace {

namespace fs = std::filesystem;

constexpr std::int64_t kFrames = 60;

scenario::Scenario video_scenario(const fs::path& dir) {
  fs::create_directories(dir);
  const fs::path file = dir / "scenario.yaml";
  std::ofstream(file) << R"(name: sensor_video
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1.0}
checkpoint: {every_s: 0.2}
vehicles:
  - id: a
    model: hmmwv
    start: {x: 0, y: 0, yaw_deg: 0}
    sensors: {rig: default, video: true}
  - id: b
    model: hmmwv
    start: {x: 8, y: 0, yaw_deg: 0}
)";
  return scenario::load_scenario(file.string(), {}, SYNDDS_TEST_CONFIG_DIR);
}

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Steps frame k: vehicle b drives away in front of a's camera.
void step(agents::SensorAgent& sensor, std::int64_t k) {
  proto::FrameContext ctx;
  ctx.frame = k;
  ctx.heartbeat_s = 0.01;
  ctx.sim_time_s = static_cast<double>(k) * ctx.heartbeat_s;
  proto::FrameSamples in, out;
  if (k > 0) {
    proto::VehicleStateMsg b;
    b.vehicle_id = "b";
    b.frame = k - 1;
    b.pose.position = Vec3(8.0 + 0.1 * static_cast<double>(k), 0.3, 0.0);
    in.vehicle_states.push_back(b);
  }
  sensor.step(ctx, in, out);
}

std::string state_of(agents::SensorAgent& sensor) {
  core::StateWriter w;
  sensor.save_state(w);
  return w.take();
}

void load(agents::SensorAgent& sensor, const std::string& state) {
  core::StateReader r(state, "sensor.a.state");
  sensor.load_state(r);
}

struct RunFiles {
  fs::path video, index;
};

RunFiles files(const fs::path& out) {
  return {out / "sensors" / "a" / "front_camera.avi", out / "sensors" / "a" / "frames.csv"};
}

agents::SensorAgentOptions options(const fs::path& out, bool resume = false) {
  return {(out / "sensors").string(), resume};
}

}  // namespace

TEST(SensorAgentVideo, RolledBackOrRestartedItEndsByteIdentical) {
  const fs::path dir = fs::path(testing::TempDir()) / "syndds-sensor-agent-video";
  fs::remove_all(dir);
  const auto s = video_scenario(dir);

  // Undisturbed.
  const RunFiles want = files(dir / "want");
  {
    agents::SensorAgent sensor(s, s.vehicles.front(), options(dir / "want"));
    EXPECT_TRUE(sensor.can_checkpoint());
    EXPECT_NO_THROW(agents::require_checkpoints(s, sensor));
    for (std::int64_t k = 0; k <= kFrames; ++k) step(sensor, k);
    sensor.finish({}, {});
  }
  ASSERT_GT(fs::file_size(want.video), 10000u);

  // Checkpoints at frame 0 (before the camera's first frame: no video yet) and frame 20.
  for (const std::int64_t at : {std::int64_t{0}, std::int64_t{20}}) {
    SCOPED_TRACE(at);
    // Rolled back in the same process from frame 45, twice.
    const fs::path out = dir / ("rollback" + std::to_string(at));
    {
      agents::SensorAgent sensor(s, s.vehicles.front(), options(out));
      std::string state;
      for (std::int64_t k = 0; k <= at; ++k) step(sensor, k);
      state = state_of(sensor);
      for (std::int64_t k = at + 1; k <= 45; ++k) step(sensor, k);
      load(sensor, state);
      if (at == 0) {
        EXPECT_FALSE(fs::exists(files(out).video));  // begun after the checkpoint
      }
      for (std::int64_t k = at + 1; k <= 30; ++k) step(sensor, k);
      load(sensor, state);
      for (std::int64_t k = at + 1; k <= kFrames; ++k) step(sensor, k);
      sensor.finish({}, {});
    }
    EXPECT_TRUE(bytes_of(files(out).video) == bytes_of(want.video));
    EXPECT_EQ(bytes_of(files(out).index), bytes_of(want.index));

    // Killed at frame 45 (the agent is never finished) and restarted on its files.
    const fs::path killed = dir / ("restart" + std::to_string(at));
    std::string state;
    {
      auto sensor = std::make_unique<agents::SensorAgent>(s, s.vehicles.front(), options(killed));
      for (std::int64_t k = 0; k <= at; ++k) step(*sensor, k);
      state = state_of(*sensor);
      for (std::int64_t k = at + 1; k <= 45; ++k) step(*sensor, k);
      // What the killed process leaves: the files as written so far.
      const std::string video = bytes_of(files(killed).video);
      sensor.reset();
      std::ofstream(files(killed).video, std::ios::binary | std::ios::trunc) << video;
    }
    {
      agents::SensorAgent sensor(s, s.vehicles.front(), options(killed, true));
      load(sensor, state);
      if (at == 0) {
        EXPECT_FALSE(fs::exists(files(killed).video));
      }
      for (std::int64_t k = at + 1; k <= kFrames; ++k) step(sensor, k);
      sensor.finish({}, {});
    }
    EXPECT_TRUE(bytes_of(files(killed).video) == bytes_of(want.video));
    EXPECT_EQ(bytes_of(files(killed).index), bytes_of(want.index));
  }
  if (!testing::Test::HasFailure()) fs::remove_all(dir);
}
