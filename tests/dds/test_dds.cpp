// In-process DDS tests: the coordinator and members as objects in one process, each with its
// own DDS participant, talking over the real Fast DDS stack; plus the type conversions.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "agents/agent_factory.hpp"
#include "core/error.hpp"
#include "dds/convert.hpp"
#include "dds/coordinator_service.hpp"
#include "dds/member_runtime.hpp"
#include "protocol/local_runner.hpp"

using namespace syndds;
namespace sdds = syndds::dds;
namespace fs = std::filesystem;

namespace {

const std::string kConfig = SYNDDS_TEST_CONFIG_DIR;

std::string read_file(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

sdds::DdsOptions dds_options(int domain, const std::string& run_id) {
  sdds::DdsOptions o;
  o.domain_id = domain;
  o.run_id = run_id;
  o.profiles_file = kConfig + "/dds/profiles.xml";
  return o;
}

}  // namespace

TEST(Convert, VehicleStateRoundTripsExactly) {
  proto::VehicleStateMsg s;
  s.vehicle_id = "v1";
  s.source = "vehicle/v1";
  s.frame = 42;
  s.sim_time_s = 0.42;
  s.pose.position = Vec3(1.0 / 3.0, -2.5, 0.467);
  s.pose.orientation = Quat(Eigen::AngleAxisd(0.3, Vec3(0.1, 0.2, 1.0).normalized()));
  s.linear_velocity = Vec3(1, 2, 3);
  s.angular_acceleration = Vec3(-1e-300, 4, 5);
  s.wheels.push_back({s.pose, 12.5, 0.1, 6000.0});
  s.steering = -0.25;
  s.throttle = 0.75;
  s.gear = 2;
  s.engine_speed_rpm = 1650.5;
  const auto back = sdds::from_dds(sdds::to_dds(s));
  EXPECT_EQ(back.vehicle_id, s.vehicle_id);
  EXPECT_EQ(back.frame, s.frame);
  EXPECT_EQ(back.pose.position, s.pose.position);
  EXPECT_EQ(back.pose.orientation.coeffs(), s.pose.orientation.coeffs());
  EXPECT_EQ(back.angular_acceleration, s.angular_acceleration);
  ASSERT_EQ(back.wheels.size(), 1u);
  EXPECT_EQ(back.wheels[0].spin_rad_s, 12.5);
  EXPECT_EQ(back.engine_speed_rpm, s.engine_speed_rpm);
  EXPECT_EQ(back.gear, 2);
}

TEST(Convert, ControlMessagesRoundTrip) {
  proto::RunControlMsg c;
  c.status = proto::RunStatus::aborted;
  c.reason = "member vehicle/a lost";
  c.final_frame = 7;
  c.final_manifest = {{proto::Topic::collision_event, "a", "vehicle/a", 2}};
  c.stats.frames = 8;
  c.stats.members = {{"vehicle/a", 0.001, 0.002, 0.0005, 3, true}};
  const auto back = sdds::from_dds(sdds::to_dds(c));
  EXPECT_EQ(back.status, proto::RunStatus::aborted);
  EXPECT_EQ(back.reason, c.reason);
  EXPECT_EQ(back.final_manifest, c.final_manifest);
  ASSERT_EQ(back.stats.members.size(), 1u);
  EXPECT_TRUE(back.stats.members[0].lost);
  EXPECT_EQ(back.stats.members[0].slowest_count, 3u);
}

TEST(Convert, MalformedSamplesAreRejectedWithTheField) {
  msg::FrameGrant g;
  msg::TopicCount c;
  c.topic("vehicle_speed");
  c.writer("vehicle/x");
  g.manifest().push_back(c);
  try {
    sdds::from_dds(g);
    FAIL() << "accepted an unknown topic";
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown topic 'vehicle_speed' (writer vehicle/x)"),
              std::string::npos)
        << e.what();
  }
  msg::TerrainDeformation t;
  t.source("vehicle/y");
  msg::TerrainVertex v;
  v.i(3);
  v.j(4);
  v.height(std::nan(""));
  t.vertices().push_back(v);
  EXPECT_THROW(sdds::from_dds(t), ProtocolError);
}

// A whole run with every agent on its own participant in this process, compared byte for byte
// with the same agents in the LocalRunner.
TEST(InProcessDds, RunMatchesTheLocalRunner) {
  scenario::Overrides o;
  o.duration_s = 0.5;
  const auto s = scenario::load_scenario(kConfig + "/scenarios/default.yaml", o);
  const fs::path dir = fs::path(testing::TempDir()) / ("syndds-inproc-" + std::to_string(getpid()));
  fs::remove_all(dir);

  proto::LocalRunner local(agents::make_all_agents(s, {(dir / "local").string(), "x", "single"}),
                           {s.time.final_frame(), s.time.heartbeat_s, false});
  ASSERT_EQ(local.run().status, proto::RunStatus::completed);

  const int domain = 230;
  const std::string run_id = "inproc-" + std::to_string(getpid());
  sdds::CoordinatorOptions co;
  co.dds = dds_options(domain, run_id);
  co.config_fingerprint = s.fingerprint;
  co.barrier.members = s.member_ids();
  co.barrier.final_frame = s.time.final_frame();
  co.barrier.heartbeat_s = s.time.heartbeat_s;
  co.barrier.join_timeout_s = 20;
  sdds::CoordinatorService coordinator(co);

  auto agents = agents::make_all_agents(s, {(dir / "dds").string(), run_id, "distributed"});
  std::atomic<bool> stop{false};
  std::vector<int> codes(agents.size(), -1);
  std::vector<std::thread> threads;
  for (std::size_t i = 0; i < agents.size(); ++i) {
    threads.emplace_back([&, i] {
      sdds::MemberRuntimeOptions mo;
      mo.dds = dds_options(domain, run_id);
      mo.config_fingerprint = s.fingerprint;
      mo.heartbeat_s = s.time.heartbeat_s;
      sdds::MemberRuntime runtime(*agents[i], mo);
      codes[i] = runtime.run(stop);
    });
  }
  const int code = coordinator.run(stop);
  for (auto& t : threads) t.join();
  EXPECT_EQ(code, sdds::kExitCompleted);
  for (int c : codes) EXPECT_EQ(c, sdds::kExitCompleted);
  EXPECT_EQ(coordinator.result().stats.frames, 51u);
  agents.clear();  // closes the recorder's files
  EXPECT_EQ(read_file(dir / "dds" / "vehicles.csv"), read_file(dir / "local" / "vehicles.csv"));
  EXPECT_EQ(read_file(dir / "dds" / "commands.csv"), read_file(dir / "local" / "commands.csv"));
  if (!HasFailure()) fs::remove_all(dir);
}
