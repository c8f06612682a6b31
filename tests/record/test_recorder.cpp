// The recorder agent driven directly, frame by frame: a full disk, ids that hold commas, the
// summary of a run that never ends properly, members lost under on_member_loss: continue.
#include <gtest/gtest.h>

#include <chrono>
#include <nlohmann/json.hpp>

#include "agents/recorder_agent.hpp"
#include "record/run_files.hpp"
#include "record_test_util.hpp"

using namespace syndds;
using namespace syndds::test;

namespace {

const std::string kTwoVehicles = R"(name: recorder_test
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 100.0}
vehicles:
  - id: a
    model: hmmwv
    controller: {type: path_follower, path: {waypoints: [[0, 0], [100, 0]]}, speed: {target_mps: 5}}
  - id: b
    model: hmmwv
    controller: {type: path_follower, path: {waypoints: [[0, 10], [100, 10]]}, speed: {target_mps: 5}}
)";

proto::FrameContext context(std::int64_t frame) {
  proto::FrameContext ctx;
  ctx.frame = frame;
  ctx.heartbeat_s = 0.01;
  ctx.sim_time_s = static_cast<double>(frame) * ctx.heartbeat_s;
  return ctx;
}

// What the vehicles publish in frame `frame` (the recorder sees it in frame + 1).
proto::FrameSamples states(std::int64_t frame, const std::vector<std::string>& ids) {
  proto::FrameSamples s;
  for (const auto& id : ids) {
    proto::VehicleStateMsg m;
    m.vehicle_id = id;
    m.source = scenario::vehicle_member(id);
    m.frame = frame;
    m.sim_time_s = static_cast<double>(frame) * 0.01;
    m.pose.position = Vec3(0.05 * static_cast<double>(frame), id == "b" ? 10.0 : 0.0, 0.5);
    m.linear_velocity = Vec3(5.0, 0.0, 0.0);
    m.throttle = 0.5;
    s.vehicle_states.push_back(m);
  }
  return s;
}

// Steps the recorder through frames [from, to) with both vehicles' states.
void run_frames(record::RecorderAgent& r, std::int64_t from, std::int64_t to) {
  for (std::int64_t k = from; k < to; ++k) {
    proto::FrameSamples out;
    r.step(context(k), k > 0 ? states(k - 1, {"a", "b"}) : proto::FrameSamples{}, out);
  }
}

proto::RunEnd aborted(const std::string& reason) {
  proto::RunEnd end;
  end.control.status = proto::RunStatus::aborted;
  end.control.reason = reason;
  return end;
}

// The end of a run of `frames` frames that completed, with no member statistics yet.
proto::RunEnd completed(std::int64_t frames) {
  proto::RunEnd end;
  end.control.status = proto::RunStatus::completed;
  end.control.final_frame = frames - 1;
  end.control.stats.frames = frames;
  end.control.stats.final_frame = frames - 1;
  return end;
}

nlohmann::json summary_of(const fs::path& dir) {
  return nlohmann::json::parse(read_file(dir / "summary.json"));
}

// Rows per frame of vehicles.csv (after the header).
std::map<long, int> rows_per_frame(const fs::path& dir) {
  std::map<long, int> rows;
  const auto csv = parse_csv(read_file(dir / "vehicles.csv"));
  for (std::size_t i = 1; i < csv.size(); ++i) ++rows[std::stol(csv[i].at(0))];
  return rows;
}

}  // namespace

// A full disk ends the run with the file and the reason; the files keep whole frames only and
// summary.json is never left empty or cut short.
TEST(Recorder, AFullDiskFailsTheFrameAndKeepsOnlyCompleteFrames) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, kTwoVehicles);
  record::RecorderAgent recorder(s, {(dir / "run").string(), "test", "single-process"});
  std::string error;
  std::int64_t failed_frame = -1;
  {
    FileSizeLimit limit(20000);
    for (std::int64_t k = 0; k < 2000 && error.empty(); ++k) {
      proto::FrameSamples out;
      try {
        recorder.step(context(k), k > 0 ? states(k - 1, {"a", "b"}) : proto::FrameSamples{}, out);
      } catch (const record::WriteError& e) {
        error = e.what();
        failed_frame = k;
      }
    }
  }
  ASSERT_FALSE(error.empty()) << "the recorder wrote 2000 frames past a 20 kB file size limit "
                                 "without an error";
  EXPECT_NE(error.find("vehicles.csv"), std::string::npos) << error;
  EXPECT_NE(error.find("large"), std::string::npos) << error;  // EFBIG: "File too large"
  const std::string csv = read_file(dir / "run" / "vehicles.csv");
  EXPECT_EQ(csv.back(), '\n') << "vehicles.csv ends inside a row";
  const auto rows = rows_per_frame(dir / "run");
  ASSERT_FALSE(rows.empty());
  for (const auto& [frame, n] : rows) EXPECT_EQ(n, 2) << "frame " << frame << " is incomplete";
  EXPECT_EQ(rows.rbegin()->first, failed_frame - 2) << "frame " << failed_frame - 1
                                                    << " failed and must not be on disk";
  // The run ends (aborted, with the reason); the summary tells the last complete frame.
  recorder.finish(aborted("recorder failed in frame " + std::to_string(failed_frame) + ": " +
                          error),
                  {});
  const auto summary = summary_of(dir / "run");
  EXPECT_EQ(summary["status"], "aborted");
  EXPECT_EQ(summary["recorded_up_to_frame"].get<long>(), rows.rbegin()->first);
}

// Once it has failed, the recorder refuses further frames (a frame after a hole is no record).
TEST(Recorder, AfterAWriteErrorEveryFurtherFrameFails) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, kTwoVehicles);
  record::RecorderAgent recorder(s, {(dir / "run").string(), "test", "single-process"});
  run_frames(recorder, 0, 3);
  bool failed = false;
  {
    FileSizeLimit limit(1000);
    for (std::int64_t k = 3; k < 100 && !failed; ++k) {
      proto::FrameSamples out;
      try {
        recorder.step(context(k), states(k - 1, {"a", "b"}), out);
      } catch (const record::WriteError&) {
        failed = true;
      }
    }
  }
  ASSERT_TRUE(failed);
  proto::FrameSamples out;
  EXPECT_THROW(recorder.step(context(200), states(199, {"a", "b"}), out), record::WriteError);
}

// Ids are text cells: a comma in a vehicle or sensor id must not shift the columns.
TEST(Recorder, IdsWithCommasQuotesOrLineBreaksKeepTheirColumn) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, R"(name: sensor_ids
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1.0}
vehicles:
  - id: a
    model: hmmwv
    start: {x: 0, y: 0, yaw_deg: 0}
    sensors: {rig: default}
)");
  record::RecorderAgent recorder(s, {(dir / "run").string(), "test", "single-process"});
  const std::string odd = "x,\"y\"\nz";
  proto::FrameSamples in = states(0, {odd});
  proto::GpsFixMsg fix;
  fix.vehicle_id = odd;
  fix.source = "vehicle/a";
  fix.stamp.sensor_id = "gps,front";
  fix.latitude_deg = 45.0;
  in.gps_fixes.push_back(fix);
  proto::VehicleEventMsg ev{odd, "controller/a", 0, 0.0, "leader_lost", "gap 3,5 m"};
  in.vehicle_events.push_back(ev);
  proto::FrameSamples out;
  recorder.step(context(0), {}, out);
  recorder.step(context(1), in, out);
  const auto vehicles = parse_csv(read_file(dir / "run" / "vehicles.csv"));
  ASSERT_EQ(vehicles.size(), 2u);
  ASSERT_EQ(vehicles[1].size(), vehicles[0].size());
  EXPECT_EQ(vehicles[1][2], odd);
  const auto gps = parse_csv(read_file(dir / "run" / "gps.csv"));
  ASSERT_EQ(gps.size(), 2u);
  ASSERT_EQ(gps[1].size(), gps[0].size());
  EXPECT_EQ(gps[1][1], odd);
  EXPECT_EQ(gps[1][2], "gps,front");
  const auto events = parse_csv(read_file(dir / "run" / "events.csv"));
  ASSERT_EQ(events.size(), 2u);
  ASSERT_EQ(events[1].size(), events[0].size());
  EXPECT_EQ(events[1][3], odd);
  EXPECT_EQ(events[1][4], "controller/a: gap 3,5 m");
}

// A recorder killed while running leaves a summary.json that says how far it got.
TEST(Recorder, SummaryStaysCurrentWhileTheRunGoesOn) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, kTwoVehicles);
  record::RecorderAgent recorder(s, {(dir / "run").string(), "test", "single-process"});
  EXPECT_EQ(summary_of(dir / "run")["recorded_up_to_frame"], -1);
  // The summary is rewritten about once per second of wall time: step until it moves on.
  std::int64_t k = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (summary_of(dir / "run")["recorded_up_to_frame"].get<long>() < 0 &&
         std::chrono::steady_clock::now() < deadline) {
    run_frames(recorder, k, k + 1);
    ++k;
  }
  const auto summary = summary_of(dir / "run");
  EXPECT_EQ(summary["status"], "running");
  const long recorded = summary["recorded_up_to_frame"].get<long>();
  EXPECT_GE(recorded, 0) << "summary.json still says nothing was recorded after " << k
                         << " frames";
  EXPECT_LE(recorded, k - 2);
  EXPECT_EQ(rows_per_frame(dir / "run").at(recorded), 2) << "frame " << recorded
                                                         << " is not complete on disk";
}

// A lost coordinator sends no run statistics: the recorder fills in what it recorded itself.
TEST(Recorder, MissingCoordinatorStatisticsAreFilledFromTheRecord) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, kTwoVehicles);
  record::RecorderAgent recorder(s, {(dir / "run").string(), "test", "distributed"});
  run_frames(recorder, 0, 51);  // frames 0..49 recorded
  recorder.finish(aborted("the coordinator was lost (its process exited or stopped answering)"),
                  {});
  const auto summary = summary_of(dir / "run");
  EXPECT_EQ(summary["status"], "aborted");
  EXPECT_EQ(summary["recorded_up_to_frame"], 49);
  EXPECT_EQ(summary["frames"], 50);
  EXPECT_EQ(summary["final_frame"], 49);
  EXPECT_NEAR(summary["sim_time_s"].get<double>(), 0.49, 1e-12);
  EXPECT_EQ(summary["stats_missing"], true);
  EXPECT_NE(read_file(dir / "run" / "summary.txt").find("statistics missing"), std::string::npos)
      << read_file(dir / "run" / "summary.txt");
}

// on_member_loss: continue: every loss is in events.csv and in the summaries.
TEST(Recorder, LostMembersAreRecorded) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, kTwoVehicles);
  record::RecorderAgent recorder(s, {(dir / "run").string(), "test", "distributed"});
  run_frames(recorder, 0, 20);
  proto::FrameContext ctx = context(20);
  ctx.departed = {"controller/b", "vehicle/b"};
  proto::FrameSamples out;
  recorder.step(ctx, states(19, {"a", "b"}), out);
  run_frames(recorder, 21, 30);
  proto::RunEnd end = completed(30);
  end.control.stats.members.push_back({});
  end.control.stats.members.back().member_id = "vehicle/b";
  end.control.stats.members.back().lost = true;
  recorder.finish(end, {});
  const auto events = parse_csv(read_file(dir / "run" / "events.csv"));
  std::vector<std::vector<std::string>> lost;
  for (const auto& e : events) {
    if (e.at(2) == "member_lost") lost.push_back(e);
  }
  ASSERT_EQ(lost.size(), 2u) << read_file(dir / "run" / "events.csv");
  EXPECT_EQ(lost[0], (std::vector<std::string>{"20", "0.2", "member_lost", "b", "controller/b"}));
  EXPECT_EQ(lost[1], (std::vector<std::string>{"20", "0.2", "member_lost", "b", "vehicle/b"}));
  const auto summary = summary_of(dir / "run");
  ASSERT_EQ(summary["losses"].size(), 2u) << summary.dump(2);
  EXPECT_EQ(summary["losses"][0]["member"], "controller/b");
  EXPECT_EQ(summary["losses"][0]["frame"], 20);
  EXPECT_NEAR(summary["losses"][0]["time_s"].get<double>(), 0.2, 1e-12);
  EXPECT_EQ(summary["losses"][1]["member"], "vehicle/b");
  const std::string text = read_file(dir / "run" / "summary.txt");
  EXPECT_NE(text.find("lost: controller/b in frame 20"), std::string::npos) << text;
}

// summary.txt's member table gives each member's own step time next to its response time: the
// members of one process answer in one sample and share the process's response time.
TEST(Recorder, TheMemberTableGivesEachMembersStepTime) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, kTwoVehicles);
  record::RecorderAgent recorder(s, {(dir / "run").string(), "test", "distributed"});
  run_frames(recorder, 0, 10);
  proto::RunEnd end = completed(10);
  for (const auto& [id, step_s] : {std::pair{"vehicle/a", 0.00125}, {"controller/a", 0.0002}}) {
    proto::MemberStatsMsg m;
    m.member_id = id;
    m.mean_response_s = 0.0031;  // one process: the same response for both
    m.max_response_s = 0.0172;
    m.mean_compute_s = step_s;
    end.control.stats.members.push_back(m);
  }
  recorder.finish(end, {});
  const std::string text = read_file(dir / "run" / "summary.txt");
  EXPECT_NE(text.find("mean_response_ms max_response_ms mean_step_ms slowest_frames"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("vehicle/a                         3.100          17.200        1.250"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("controller/a                      3.100          17.200        0.200"),
            std::string::npos)
      << text;
}

// recorder.skip: the skipped files are neither written nor subscribed to, and the others are
// byte for byte those of a recorder that skips nothing.
TEST(Recorder, SkippedFilesAreNeitherWrittenNorSubscribedTo) {
  const fs::path dir = test_dir();
  const auto all = scenario_from(dir, kTwoVehicles);
  const auto some = scenario_from(dir, kTwoVehicles + "recorder: {skip: [commands, wheels]}\n");
  record::RecorderAgent plain(all, {(dir / "plain").string(), "test", "distributed"});
  record::RecorderAgent skipping(some, {(dir / "skipping").string(), "test", "distributed"});
  const auto topics = [](const record::RecorderAgent& r) {
    std::set<proto::Topic> t;
    for (const auto& s : r.subscriptions()) t.insert(s.topic);
    return t;
  };
  EXPECT_TRUE(topics(plain).count(proto::Topic::driver_command));
  EXPECT_FALSE(topics(skipping).count(proto::Topic::driver_command));
  EXPECT_TRUE(topics(skipping).count(proto::Topic::vehicle_state));
  for (std::int64_t k = 0; k < 20; ++k) {
    proto::FrameSamples in = k > 0 ? states(k - 1, {"a", "b"}) : proto::FrameSamples{};
    for (auto& st : in.vehicle_states) {
      st.wheels.resize(4);
      proto::DriverCommandMsg c;
      c.vehicle_id = st.vehicle_id;
      c.source = scenario::controller_member(st.vehicle_id);
      c.frame = k - 1;
      c.throttle = 0.5;
      in.driver_commands.push_back(c);  // given to both: a skipping recorder ignores them
    }
    proto::FrameSamples out;
    plain.step(context(k), in, out);
    skipping.step(context(k), in, out);
  }
  plain.finish(completed(20), {});
  skipping.finish(completed(20), {});
  for (const char* file : {"vehicles.csv", "events.csv"}) {
    EXPECT_EQ(read_file(dir / "skipping" / file), read_file(dir / "plain" / file)) << file;
  }
  EXPECT_GT(parse_csv(read_file(dir / "plain" / "commands.csv")).size(), 30u);
  EXPECT_GT(parse_csv(read_file(dir / "plain" / "wheels.csv")).size(), 100u);
  EXPECT_FALSE(fs::exists(dir / "skipping" / "commands.csv"));
  EXPECT_FALSE(fs::exists(dir / "skipping" / "wheels.csv"));
}
