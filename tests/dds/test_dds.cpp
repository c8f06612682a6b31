// In-process DDS tests: the coordinator and members as objects in one process, each with its
// own DDS participant, talking over the real Fast DDS stack (the type conversions are tested in
// test_convert.cpp).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "agents/agent_factory.hpp"
#include "dds/coordinator_service.hpp"
#include "dds/member_runtime.hpp"
#include "dds_test_util.hpp"
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

using dds_test::options;

}  // namespace

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
  co.dds = options(domain, run_id);
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
      mo.dds = options(domain, run_id);
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
