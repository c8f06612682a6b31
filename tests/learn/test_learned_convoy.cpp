// The shipped learned follower (config/policies/convoy_follow_lowdim.pt) in a 1L+1F convoy on
// rigid ground with the real programs: the policy runs in its own process
// (syndds_policy_controller) over DDS, follows the leader over the whole path without hitting
// an obstacle or losing it, and the run equals the single-process run byte for byte.
#include <nlohmann/json.hpp>

#include "harness.hpp"

using namespace syndds::test;

TEST(LearnedConvoy, ShippedPolicyFollowsOverTheWholePathDistributed) {
  TestRun run;
  const std::string scenario = kConfig + "/scenarios/learned/1L1F_rigid_policy.yaml";
  const std::string single = single_process_csv(run, scenario, "");
  auto launcher = start_launcher(run, scenario);
  const auto code = launcher->wait(150.0);
  ASSERT_TRUE(code.has_value()) << "launcher still running";
  ASSERT_EQ(*code, 0) << launcher->log();
  const fs::path out = run.dir / "out";
  EXPECT_EQ(read_file(out / "vehicles.csv"), single);
  // The policy ran in the program that loads libtorch; the leader's path follower did not.
  EXPECT_NE(read_file(out / "logs" / "controller_f1.log").find("[policy_controller]"),
            std::string::npos);
  EXPECT_NE(read_file(out / "logs" / "controller_l1.log").find("[controller]"), std::string::npos);

  const auto summary = nlohmann::json::parse(read_file(out / "summary.json"));
  ASSERT_EQ(summary["status"], "completed");
  // The leader's path is about 211 m long; the follower stops about one gap behind its end.
  const auto& vehicles = summary["vehicles"];
  double leader_m = 0.0, follower_m = 0.0;
  for (const auto& v : vehicles) {
    if (v["id"] == "l1") leader_m = v["distance_m"].get<double>();
    if (v["id"] == "f1") follower_m = v["distance_m"].get<double>();
  }
  EXPECT_GT(leader_m, 200.0) << summary.dump();
  EXPECT_GT(follower_m, 185.0) << summary.dump();
  const auto report = nlohmann::json::parse(read_file(out / "convoy.json"));
  ASSERT_EQ(report.size(), 1u);
  EXPECT_EQ(report[0]["leader_lost_events"], 0);
  EXPECT_EQ(report[0]["obstacles_hit"], 0);
  const auto metrics = nlohmann::json::parse(read_file(out / "metrics.json"));
  ASSERT_EQ(metrics["followers"].size(), 1u);
  EXPECT_LT(metrics["followers"][0]["m_p_avg"].get<double>(), 1.5) << metrics.dump();
}
