// metrics.json: the recorder driven frame by frame with constructed tracks of a convoy l1 <- f1
// <- f2 writes the paper's deviation metrics per follower, each against the head of its chain.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "agents/recorder_agent.hpp"
#include "record_test_util.hpp"

using namespace syndds;
using namespace syndds::test;

namespace {

// l1 leads; f1 follows l1, f2 follows f1 (only the recorder is driven: the controllers and
// sensors are not run).
const std::string kConvoy = R"(name: metrics_test
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 100.0}
vehicles:
  - id: l1
    model: hmmwv
    sensors: convoy
    v2v: {rate_hz: 10}
    controller: {type: path_follower, path: {waypoints: [[0, 0], [100, 0]]}, speed: {target_mps: 5}}
  - id: f1
    model: hmmwv
    start: {x: -12, y: 0}
    sensors: convoy
    v2v: {rate_hz: 10}
    controller: {type: follower, follow: l1}
  - id: f2
    model: hmmwv
    start: {x: -24, y: 0}
    sensors: convoy
    controller: {type: follower, follow: f1}
)";

// Frame k: l1 at x = 0.05 k on y = 0 at 5 m/s; f1 12 m behind, 0.5 m to the left, as fast;
// f2 24 m behind on the line, reporting 4 m/s, hitting a rock in frames 500 and 600.
proto::FrameSamples states(std::int64_t k) {
  proto::FrameSamples s;
  const double x = 0.05 * static_cast<double>(k);
  for (const auto& [id, p, v] : {std::tuple{"l1", Vec3(x, 0, 0.5), 5.0},
                                 std::tuple{"f1", Vec3(x - 12, 0.5, 0.5), 5.0},
                                 std::tuple{"f2", Vec3(x - 24, 0, 0.5), 4.0}}) {
    proto::VehicleStateMsg m;
    m.vehicle_id = id;
    m.source = scenario::vehicle_member(id);
    m.frame = k;
    m.sim_time_s = static_cast<double>(k) * 0.01;
    m.pose.position = p;
    m.linear_velocity = Vec3(v, 0.0, 0.0);
    s.vehicle_states.push_back(m);
  }
  if (k == 500 || k == 600) {  // f2 hits a rock twice
    proto::CollisionEventMsg c;
    c.vehicle_id = "f2";
    c.source = scenario::vehicle_member("f2");
    c.frame = k;
    c.sim_time_s = static_cast<double>(k) * 0.01;
    c.obstacle_id = "rock";
    s.collision_events.push_back(c);
  }
  return s;
}

proto::RunEnd completed() {
  proto::RunEnd end;
  end.control.status = proto::RunStatus::completed;
  return end;
}

// Runs frames 0..1000 (l1 drives 50 m) and returns metrics.json.
nlohmann::json run_convoy(const fs::path& dir) {
  fs::create_directories(dir);
  const auto s = scenario_from(dir, kConvoy);
  record::RecorderAgent recorder(s, {(dir / "run").string(), "test", "single-process"});
  for (std::int64_t k = 0; k <= 1000; ++k) {
    proto::FrameSamples out;
    proto::FrameContext ctx;
    ctx.frame = k;
    ctx.heartbeat_s = 0.01;
    ctx.sim_time_s = static_cast<double>(k) * 0.01;
    recorder.step(ctx, k > 0 ? states(k - 1) : proto::FrameSamples{}, out);
  }
  recorder.finish(completed(), states(1000));
  EXPECT_EQ(recorder.follower_metrics().size(), 2u);
  return nlohmann::json::parse(read_file(dir / "run" / "metrics.json"));
}

}  // namespace

TEST(MetricsFile, ARunWithFollowersWritesTheDeviationMetrics) {
  const fs::path dir = test_dir();
  const auto j = run_convoy(dir);
  EXPECT_EQ(j["spacing_m"], 0.5);
  EXPECT_EQ(j["speed_skip_m"], 10.0);
  EXPECT_EQ(j["min_leader_speed_mps"], 0.5);
  ASSERT_EQ(j["followers"].size(), 2u);

  // f1 drives l1's line 0.5 m to the side at its speed; the common segment ends where f1
  // ended (x = 38 m): samples 0, 0.5, ..., 38 m, the speed ones from 10 m on.
  const auto& f1 = j["followers"][0];
  EXPECT_EQ(f1["id"], "f1");
  EXPECT_EQ(f1["leader"], "l1");
  EXPECT_EQ(f1["follows"], "l1");
  EXPECT_EQ(f1["position"], 1);
  EXPECT_EQ(f1["m_p_avg"], 0.5);
  EXPECT_EQ(f1["m_p_max"], 0.5);
  EXPECT_EQ(f1["m_as_avg"], 0.0);
  EXPECT_EQ(f1["m_as_max"], 0.0);
  EXPECT_EQ(f1["m_rs_avg"], 0.0);
  EXPECT_EQ(f1["m_rs_max"], 0.0);
  EXPECT_EQ(f1["obstacles_hit"], 0);
  // 12 m behind its leader, 0.5 m aside: 12 - 4.7 m between the HMMWVs' boxes, never below
  // the standstill gap.
  EXPECT_EQ(f1["min_bumper_gap_m"], 7.3);
  EXPECT_EQ(f1["time_below_standstill_s"], 0.0);
  EXPECT_EQ(f1["samples"], 77);
  EXPECT_EQ(f1["speed_samples"], 57);
  EXPECT_EQ(f1["relative_speed_samples"], 57);
  EXPECT_EQ(f1["segment_length_m"], 38.0);
  EXPECT_EQ(f1["follower_segment_length_m"], 38.0);
  EXPECT_EQ(f1["follower_start_time_s"], 2.4);  // where f1 passed x = 0
  EXPECT_EQ(f1["leader_end_time_s"], 7.6);      // where l1 was at x = 38 m

  // f2 follows f1 but is measured against l1, the head of its chain: on the line, 1 m/s slow.
  const auto& f2 = j["followers"][1];
  EXPECT_EQ(f2["id"], "f2");
  EXPECT_EQ(f2["leader"], "l1");
  EXPECT_EQ(f2["follows"], "f1");
  EXPECT_EQ(f2["position"], 2);
  EXPECT_EQ(f2["m_p_max"], 0.0);
  EXPECT_EQ(f2["m_as_avg"], 1.0);
  EXPECT_EQ(f2["m_as_max"], 1.0);
  EXPECT_EQ(f2["m_rs_avg"], 0.2);
  EXPECT_EQ(f2["m_rs_max"], 0.2);
  EXPECT_EQ(f2["obstacles_hit"], 2);
  EXPECT_EQ(f2["samples"], 53);  // 0, ..., 26 m
  EXPECT_EQ(f2["speed_samples"], 33);
  EXPECT_EQ(f2["segment_length_m"], 26.0);

  // The head of the chain: 5 m/s in every frame, 50 m driven (frames 0..1000).
  ASSERT_EQ(j["leaders"].size(), 1u);
  EXPECT_EQ(j["leaders"][0]["id"], "l1");
  EXPECT_EQ(j["leaders"][0]["max_speed_mps"], 5.0);
  EXPECT_EQ(j["leaders"][0]["mean_moving_speed_mps"], 5.0);
  EXPECT_EQ(j["leaders"][0]["distance_m"], 50.0);

  // The run's summaries carry them too: the same document in summary.json, a table for people.
  const auto summary = nlohmann::json::parse(read_file(dir / "run" / "summary.json"));
  EXPECT_EQ(summary["metrics"], j);
  const std::string text = read_file(dir / "run" / "summary.txt");
  EXPECT_NE(text.find("m_p m avg/max"), std::string::npos) << text;
  EXPECT_NE(text.find("f2         l1              2      0.00/0.00        1.00/1.00      0.200/0.200"),
            std::string::npos)
      << text;
}

// metrics_samples.csv: every sample of both followers, the distances and speeds behind the
// averages above (f1 0.5 m aside at 5 m/s, f2 on the line at 4 m/s), every 0.5 m.
TEST(MetricsFile, TheSamplesAlongTheLeadersPathAreWrittenToo) {
  const fs::path dir = test_dir();
  run_convoy(dir);
  const std::string text = read_file(dir / "run" / "metrics_samples.csv");
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "follower,position,leader,arc_m,path_m,leader_speed_mps,follower_speed_mps");
  std::map<std::string, int> rows;
  while (std::getline(in, line)) {
    const int k = rows[line.substr(0, 2)]++;
    const double arc = 0.5 * k;
    if (line.starts_with("f1,")) {
      EXPECT_EQ(line, fmt::format("f1,1,l1,{:.9g},0.5,5,5", arc));
    } else {
      EXPECT_EQ(line, fmt::format("f2,2,l1,{:.9g},0,5,4", arc));
    }
  }
  EXPECT_EQ(rows["f1"], 77);
  EXPECT_EQ(rows["f2"], 53);
}

// Same input, same bytes (the distributed and single-process runs feed the recorder the same).
TEST(MetricsFile, IsTheSameByteForByteForTheSameRun) {
  const fs::path dir = test_dir();
  run_convoy(dir / "a");
  run_convoy(dir / "b");
  EXPECT_EQ(read_file(dir / "a" / "run" / "metrics.json"),
            read_file(dir / "b" / "run" / "metrics.json"));
}

TEST(MetricsFile, NoFollowersNoFile) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, R"(name: alone
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1.0}
vehicles:
  - id: a
    model: hmmwv
    controller: {type: path_follower, path: {waypoints: [[0, 0], [100, 0]]}, speed: {target_mps: 5}}
)");
  record::RecorderAgent recorder(s, {(dir / "run").string(), "test", "single-process"});
  recorder.finish(completed(), {});
  EXPECT_FALSE(fs::exists(dir / "run" / "metrics.json"));
  EXPECT_TRUE(recorder.follower_metrics().empty());
}

// Two followers following each other have no leader to be measured against. The scenario
// loader refuses such a file (tests/scenario); a scenario built in code (a learning
// environment, a test) is refused by the recorder when it starts, naming the file and the
// chain.
TEST(MetricsFile, AFollowChainWithoutALeaderIsAnError) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, R"(name: circle
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1.0}
vehicles:
  - id: a
    model: hmmwv
    start: {x: 0, y: 0}
    sensors: convoy
    v2v: {rate_hz: 10}
    controller: {type: path_follower, path: {waypoints: [[0, 0], [100, 0]]}, speed: {target_mps: 5}}
  - id: b
    model: hmmwv
    start: {x: -12, y: 0}
    sensors: convoy
    v2v: {rate_hz: 10}
    controller: {type: follower, follow: a}
)");
  auto circle = s;
  circle.vehicles[0].controller.type = "follower";
  circle.vehicles[0].controller.convoy = s.vehicles[1].controller.convoy;
  circle.vehicles[0].controller.convoy.leader = "b";
  try {
    record::RecorderAgent recorder(circle, {(dir / "run").string(), "test", "single-process"});
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("scenario.yaml"), std::string::npos) << what;
    EXPECT_NE(what.find("controller.follow"), std::string::npos) << what;
    EXPECT_NE(what.find("a -> b -> a"), std::string::npos) << what;
  }
}
