// The leader's emergency stop (config/scenarios/convoy/leader_emergency_stop_<terrain>.yaml) in
// one process: the leader brakes fully at a given time, the classical follower behind it must
// stop without touching it, at least 1 m between the bumpers. A few of the stop times of
// tools/leader_emergency_stop.py's study (docs/convoy.md): on each terrain the one that left the
// smallest gap there, and the one that did among the stops at the leader's top speed. Each run
// is the study's run (same scenario, single process).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "agents/agent_factory.hpp"
#include "agents/recorder_agent.hpp"
#include "protocol/local_runner.hpp"

using namespace syndds;
namespace fs = std::filesystem;

namespace {

const std::string kConfig = SYNDDS_TEST_CONFIG_DIR;

std::string read_file(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void replace(std::string& text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  ASSERT_NE(pos, std::string::npos) << from;
  text.replace(pos, from.size(), to);
}

struct StopCase {
  std::string terrain;
  double stop_at_s;
};

std::ostream& operator<<(std::ostream& o, const StopCase& c) {
  return o << c.terrain << " at " << c.stop_at_s << " s";
}

class EmergencyStop : public testing::TestWithParam<StopCase> {};

}  // namespace

TEST_P(EmergencyStop, TheFollowerStopsAtLeastOneMetreBehind) {
  const StopCase& c = GetParam();
  std::string text =
      read_file(kConfig + "/scenarios/convoy/leader_emergency_stop_" + c.terrain + ".yaml");
  const std::string stop = std::to_string(c.stop_at_s);
  replace(text, "stop_at_s: 12\n", "stop_at_s: " + stop + "\n");
  // As the study: 10 s after the stop (both stand still long before).
  replace(text, "end_time_s: 22}", "end_time_s: " + std::to_string(c.stop_at_s + 10.0) + "}");
  const fs::path dir = fs::path(testing::TempDir()) / ("stop-" + c.terrain + "-" + stop);
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "scenario.yaml") << text;
  const auto s = scenario::load_scenario((dir / "scenario.yaml").string(), {}, kConfig);
  auto agents = agents::make_all_agents(s, {(dir / "out").string(), "stop", "single-process"});
  record::RecorderAgent* recorder = nullptr;
  for (auto& a : agents) {
    if (a->member_id() == "recorder") recorder = dynamic_cast<record::RecorderAgent*>(a.get());
  }
  ASSERT_NE(recorder, nullptr);
  proto::LocalRunner runner(std::move(agents), {s.time.final_frame(), s.time.heartbeat_s, false});
  ASSERT_EQ(runner.run().status, proto::RunStatus::completed);

  // The leader was moving when it braked, and both stand still at the end.
  const auto& l1 = recorder->tracks().at("l1");
  const auto& f1 = recorder->tracks().at("f1");
  double leader_speed = 0.0;
  for (const auto& p : l1) {
    if (p.time_s <= c.stop_at_s) leader_speed = p.speed_mps;
  }
  EXPECT_GT(leader_speed, 3.0);
  EXPECT_LT(l1.back().speed_mps, 0.1);
  EXPECT_LT(f1.back().speed_mps, 0.3);
  // No contact (nothing else to hit here), and at least 1 m between the bumpers.
  EXPECT_EQ(recorder->totals().at("f1").collisions, 0u);
  EXPECT_EQ(recorder->totals().at("l1").collisions, 0u);
  ASSERT_EQ(recorder->convoy_report().size(), 1u);
  const auto& r = recorder->convoy_report()[0];
  EXPECT_GE(r.bumper_gap_m.min, 1.0) << "at t = " << r.min_bumper_gap_time_s << " s";
}

// Filled in from the study's table (docs/convoy.md, "Leader emergency stop").
INSTANTIATE_TEST_SUITE_P(Study, EmergencyStop,
                         testing::Values(StopCase{"rigid", 4.14}, StopCase{"rigid", 15.81},
                                         StopCase{"scm_hard", 3.61}, StopCase{"scm_hard", 19.48},
                                         StopCase{"scm_soft", 9.5}, StopCase{"scm_soft", 8.96}),
                         [](const testing::TestParamInfo<StopCase>& i) {
                           std::ostringstream name;
                           name << i.param.terrain << "_" << i.index;
                           return name.str();
                         });
