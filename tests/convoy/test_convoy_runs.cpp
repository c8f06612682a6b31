// Whole convoys in one process (LocalRunner: the same agents and frame semantics as the
// distributed run): the follower closes the loop through the real vehicle, sensors and V2V.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "agents/agent_factory.hpp"
#include "core/yaml.hpp"
#include "protocol/local_runner.hpp"
#include "agents/recorder_agent.hpp"

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

struct RunResult {
  proto::RunStatus status = proto::RunStatus::aborted;
  std::vector<convoy::FollowerReport> report;
  std::map<std::string, record::VehicleTotals> totals;
  std::map<std::string, convoy::Track> tracks;
};

// Runs a scenario text in one process; `name` names its output folder.
RunResult run_text(const std::string& text, const std::string& name,
                   std::optional<double> duration = std::nullopt) {
  const fs::path dir = fs::path(testing::TempDir()) / ("convoy-" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path file = dir / "scenario.yaml";
  std::ofstream(file) << text;
  scenario::Overrides o;
  o.duration_s = duration;
  const auto s = scenario::load_scenario(file.string(), o, kConfig);
  auto agents = agents::make_all_agents(s, {(dir / "out").string(), name, "single-process"});
  record::RecorderAgent* recorder = nullptr;
  for (auto& a : agents) {
    if (a->member_id() == "recorder") recorder = dynamic_cast<record::RecorderAgent*>(a.get());
  }
  EXPECT_NE(recorder, nullptr);
  proto::LocalRunner runner(std::move(agents), {s.time.final_frame(), s.time.heartbeat_s, false});
  RunResult r;
  r.status = runner.run().status;
  r.report = recorder->convoy_report();
  r.totals = recorder->totals();
  r.tracks = recorder->tracks();
  return r;
}

// A leader (reduced model) on `path` at a constant speed and one follower 12 m behind it.
std::string two_vehicle_convoy(const std::string& path, double speed, double drop = 0.0) {
  std::ostringstream t;
  t << "name: follower_test\nseed: 5\n"
    << "time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 40}\n"
    << "vehicles:\n"
    << "  - id: l1\n    model: hmmwv\n    sensors: convoy\n"
    << "    v2v: {rate_hz: 10, drop_probability: " << drop << "}\n"
    << "    controller:\n      type: path_follower\n      path: {waypoints: " << path << "}\n"
    << "      speed: {target_mps: " << speed << "}\n"
    << "  - id: f1\n    model: hmmwv\n    start: {x: -12, y: 0}\n    sensors: convoy\n"
    << "    controller: {type: follower, follow: l1, gap: {time_s: 1.0, standstill_bumper_m: 5.3}}\n";
  return t.str();
}

std::uint64_t events_of(const RunResult& r, const std::string& vehicle, const std::string& kind) {
  const auto& e = r.totals.at(vehicle).events;
  const auto it = e.find(kind);
  return it == e.end() ? 0 : it->second;
}

// A shipped convoy scenario without its chase camera: the last follower keeps the convoy rig
// (the same sensors the follower drives by, so the same results), and the run does not render
// the video, which costs about three quarters of a convoy run's time in one process.
std::string shipped(const std::string& name) {
  std::string text = read_file(kConfig + "/scenarios/convoy/" + name + ".yaml");
  const std::string chase = "sensors: {rig: convoy_chase, video: true}";
  const auto pos = text.find(chase);
  EXPECT_NE(pos, std::string::npos) << name << " has no chase camera any more";
  if (pos != std::string::npos) text.replace(pos, chase.size(), "sensors: convoy");
  return text;
}

// First time the vehicle's track reaches x >= x_min (infinity if never).
double time_to_reach(const convoy::Track& track, double x_min) {
  for (const auto& p : track) {
    if (p.position.x() >= x_min) return p.time_s;
  }
  return std::numeric_limits<double>::infinity();
}

}  // namespace

TEST(ConvoyRun, FollowerDrivesTheCornerWhereTheLeaderDroveIt) {
  // A right-angle corner (rounded by the spline to about a 10 m radius) at 6 m/s.
  const auto r = run_text(two_vehicle_convoy("[[0, 0], [60, 0], [60, 80]]", 6.0), "corner");
  ASSERT_EQ(r.status, proto::RunStatus::completed);
  ASSERT_EQ(r.report.size(), 1u);
  const auto& f = r.report[0];
  EXPECT_GT(f.cross_track_m.samples, 1000u);
  EXPECT_LT(f.cross_track_m.mean, 0.3);
  EXPECT_LT(f.cross_track_m.max, 0.8);
  EXPECT_EQ(f.leader_lost_events, 0u);
  // It went round the corner and on up the second leg.
  EXPECT_GT(r.tracks.at("f1").back().position.y(), 40.0);
}

TEST(ConvoyRun, GapSettlesAtStandstillPlusTimeGapTimesSpeed) {
  const auto r = run_text(two_vehicle_convoy("[[0, 0], [400, 0]]", 6.0), "gap");
  ASSERT_EQ(r.status, proto::RunStatus::completed);
  const auto& l = r.tracks.at("l1");
  const auto& f = r.tracks.at("f1");
  // From 25 s on (both at 6 m/s): gap 10 m + 1.0 s * 6 m/s = 16 m, within GPS noise.
  double worst = 0.0;
  for (std::size_t k = 0; k < f.size(); ++k) {
    if (f[k].time_s < 25.0) continue;
    const double gap = (l[k].position - f[k].position).norm();
    worst = std::max(worst, std::abs(gap - 16.0));
    EXPECT_NEAR(f[k].speed_mps, 6.0, 0.5);
  }
  EXPECT_LT(worst, 1.5);
}

TEST(ConvoyRun, TwentyPercentV2VDropStillCompletesThePath) {
  std::string text = shipped("1L3F_rigid");
  for (auto pos = text.find("drop_probability: 0.0"); pos != std::string::npos;
       pos = text.find("drop_probability: 0.0", pos)) {
    text.replace(pos, 21, "drop_probability: 0.2");
  }
  const auto r = run_text(text, "drop20");
  ASSERT_EQ(r.status, proto::RunStatus::completed);
  ASSERT_EQ(r.report.size(), 3u);
  for (const auto& f : r.report) {
    SCOPED_TRACE(f.follower);
    EXPECT_EQ(f.leader_lost_events, 0u);
    EXPECT_EQ(f.obstacles_hit, 0u);
    EXPECT_LT(f.cross_track_m.mean, 0.5);
    // The path ends at x = 200: every follower stops within its standstill gaps of the end.
    EXPECT_GT(r.tracks.at(f.follower).back().position.x(), 150.0);
    // Never closer than 2 m bumper to bumper (the leaders brake to their stop at the end).
    EXPECT_GE(f.bumper_gap_m.min, 2.0) << "at t = " << f.min_bumper_gap_time_s << " s";
  }
}

TEST(ConvoyRun, CutV2VStopsTheFollowerWhichReportsItsLeaderLost) {
  std::string text = shipped("1L3F_rigid");
  const auto pos = text.find("drop_probability: 0.0");  // the leader's link only
  text.replace(pos, 21, "drop_probability: 1.0");
  const auto r = run_text(text, "cut", 15.0);
  ASSERT_EQ(r.status, proto::RunStatus::completed);
  EXPECT_EQ(events_of(r, "f1", "leader_lost"), 1u);
  EXPECT_EQ(events_of(r, "f1", "leader_found"), 0u);
  // f1 never moved off its start; the leader drove on.
  const auto& f1 = r.tracks.at("f1");
  EXPECT_LT((f1.back().position - f1.front().position).norm(), 1.0);
  EXPECT_GT(r.tracks.at("l1").back().position.x(), 40.0);
}

TEST(ConvoyRun, SoftSoilSlowsTheConvoyDown) {
  const auto rigid = run_text(shipped("1L3F_rigid"), "rigid");
  const auto soft = run_text(shipped("1L3F_scm_soft"), "soft");
  ASSERT_EQ(rigid.status, proto::RunStatus::completed);
  ASSERT_EQ(soft.status, proto::RunStatus::completed);
  // The leader's target rises to 8 m/s: reached on rigid ground, not on soft soil.
  EXPECT_GT(rigid.totals.at("l1").max_speed_mps, 7.5);
  EXPECT_LT(soft.totals.at("l1").max_speed_mps, 7.2);
  for (const std::string v : {"l1", "f3"}) {
    SCOPED_TRACE(v);
    const double t_rigid = time_to_reach(rigid.tracks.at(v), 150.0);
    const double t_soft = time_to_reach(soft.tracks.at(v), 150.0);
    EXPECT_LT(t_rigid, 60.0);
    EXPECT_GT(t_soft, t_rigid + 2.0);
  }
  for (const auto* run : {&rigid, &soft}) {
    for (const auto& f : run->report) {
      SCOPED_TRACE(f.follower);
      EXPECT_EQ(f.leader_lost_events, 0u);
      EXPECT_EQ(f.obstacles_hit, 0u);
      EXPECT_GE(f.bumper_gap_m.min, 2.0) << "at t = " << f.min_bumper_gap_time_s << " s";
    }
  }
}
