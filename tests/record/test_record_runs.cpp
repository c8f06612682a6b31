// The run directory when things go wrong, with the real programs: a recorder that cannot write
// (a full tmpfs, or a file size limit: the write fails with EFBIG instead of ENOSPC), a recorder
// or a coordinator killed with SIGKILL.
#include <nlohmann/json.hpp>

#include "harness.hpp"

using namespace syndds;
using namespace syndds::test;

namespace {

const std::string kTwo = kSource + "/tests/multiprocess/scenarios/two_vehicles.yaml";
const std::string kLong = kSource + "/tests/multiprocess/scenarios/long_run.yaml";
// 300 kB: room for the recorder's 256 kB space reserve, not for 20 s of two vehicles (550 kB).
constexpr int kLimitBlocks = 600;

// `command` with files limited to `blocks` * 512 bytes (SIGXFSZ ignored, so writes fail instead).
std::string with_file_limit(const std::string& command, int blocks) {
  return "/bin/sh -c 'trap \"\" XFSZ; ulimit -f " + std::to_string(blocks) + "; exec " +
         command + "'";
}

// summary.json, or null while it does not exist yet.
nlohmann::json summary_of(const fs::path& out) {
  const auto j = nlohmann::json::parse(read_file(out / "summary.json"), nullptr, false);
  return j.is_discarded() ? nlohmann::json() : j;
}

// Rows per frame in vehicles.csv; fails the test if the file ends inside a row.
std::map<long, int> rows_per_frame(const fs::path& out) {
  const std::string csv = read_file(out / "vehicles.csv");
  EXPECT_TRUE(!csv.empty() && csv.back() == '\n') << "vehicles.csv ends inside a row";
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);  // header
  std::map<long, int> rows;
  while (std::getline(in, line)) ++rows[std::stol(line.substr(0, line.find(',')))];
  return rows;
}

std::size_t member_index(const std::vector<Planned>& processes, const std::string& member) {
  for (std::size_t i = 0; i < processes.size(); ++i) {
    if (processes[i].member == member) return i;
  }
  throw std::runtime_error("no planned process for " + member);
}

}  // namespace

// Before: "completed", exit 0, vehicles.csv cut in the middle of a row.
TEST(RecorderFailure, AFullDiskFailsTheSingleProcessRun) {
  TestRun run;
  const fs::path out = run.dir / "out";
  Process sim(with_file_limit(kBin + "/syndds_sim " + kTwo + " --duration 20 --quiet --output " +
                                  out.string() + run.common_args(),
                              kLimitBlocks),
              run.dir / "sim.log");
  const auto code = sim.wait(60);
  ASSERT_TRUE(code.has_value()) << sim.log();
  EXPECT_NE(*code, 0) << sim.log();
  // The largest file hits the limit first (wheels.csv: four rows per vehicle and frame).
  EXPECT_NE(sim.log().find("wheels.csv: cannot write: File too large"), std::string::npos)
      << sim.log();
  const auto rows = rows_per_frame(out);
  ASSERT_FALSE(rows.empty());
  long expected = 0;
  for (const auto& [frame, n] : rows) {
    EXPECT_EQ(frame, expected++);
    EXPECT_EQ(n, 2) << "frame " << frame;
  }
  EXPECT_LT(rows.rbegin()->first, 2000);  // it did stop early
  const auto summary = summary_of(out);
  ASSERT_FALSE(summary.is_null()) << "summary.json is empty or cut short";
  EXPECT_EQ(summary["status"], "aborted");
  EXPECT_NE(summary["reason"].get<std::string>().find("File too large"), std::string::npos);
  EXPECT_EQ(summary["recorded_up_to_frame"].get<long>(), rows.rbegin()->first);
}

// A real full disk: a 1 MB tmpfs as the run directory (mounted in a private mount namespace,
// the run directory copied out before the namespace goes). Before: exit 0 and "completed" with
// vehicles.csv cut mid-row; then, without room for it, a summary still saying "running", -1.
TEST(RecorderFailure, ARealFullDiskEndsTheRunWithTheReasonInTheSummary) {
  TestRun run;
  const fs::path disk = run.dir / "disk";
  const fs::path copy = run.dir / "copy";
  fs::create_directories(disk);
  const std::string script =
      "mount -t tmpfs -o size=1m tmpfs " + disk.string() + " && { " + kBin + "/syndds_sim " +
      kConfig + "/scenarios/default.yaml --duration 30 --quiet --output " +
      (disk / "run").string() + run.common_args() + "; code=$?; cp -r " +
      (disk / "run").string() + " " + copy.string() + "; exit $code; }";
  Process sim("unshare -rm /bin/sh -c '" + script + "'", run.dir / "sim.log");
  const auto code = sim.wait(120);
  ASSERT_TRUE(code.has_value()) << sim.log();
  EXPECT_NE(*code, 0) << sim.log();
  EXPECT_NE(sim.log().find("No space left on device"), std::string::npos) << sim.log();
  const auto rows = rows_per_frame(copy);
  ASSERT_FALSE(rows.empty());
  for (const auto& [frame, n] : rows) EXPECT_EQ(n, 3) << "frame " << frame;
  const auto summary = summary_of(copy);
  ASSERT_FALSE(summary.is_null()) << "summary.json is empty or cut short";
  EXPECT_EQ(summary["status"], "aborted") << summary.dump(2);
  EXPECT_NE(summary["reason"].get<std::string>().find("No space left on device"),
            std::string::npos);
  EXPECT_EQ(summary["recorded_up_to_frame"].get<long>(), rows.rbegin()->first);
  EXPECT_FALSE(fs::exists(copy / ".summary_reserve"));
}

// The recorder process cannot write: it fails, the coordinator aborts the run with its reason.
TEST(RecorderFailure, AFullDiskAtTheRecorderAbortsTheDistributedRun) {
  TestRun run;
  const fs::path out = run.dir / "out";
  const auto processes = plan(run, kTwo, out.string(), "--duration 20");
  auto procs = start_all(run, processes, [](const Planned& p) {
    return p.member == "recorder" ? with_file_limit(p.command, kLimitBlocks) : p.command;
  });
  const auto codes = wait_all(procs, 90.0);
  const std::size_t recorder = member_index(processes, "recorder");
  const std::size_t coordinator = member_index(processes, "coordinator");
  EXPECT_NE(codes[recorder], 0) << describe_logs(procs);
  EXPECT_NE(codes[recorder], -1) << describe_logs(procs);
  EXPECT_NE(codes[coordinator], 0) << describe_logs(procs);
  EXPECT_NE(procs[coordinator]->log().find("File too large"), std::string::npos)
      << procs[coordinator]->log();
  for (const auto& [frame, n] : rows_per_frame(out)) EXPECT_EQ(n, 2) << "frame " << frame;
  const auto summary = summary_of(out);
  ASSERT_FALSE(summary.is_null()) << "summary.json is empty or cut short";
  EXPECT_EQ(summary["status"], "aborted");
}

// Before: status "running" and recorded_up_to_frame -1 with thousands of frames on disk.
TEST(RecorderFailure, AKilledRecorderLeavesACurrentSummary) {
  TestRun run;
  const fs::path out = run.dir / "out";
  const auto processes = plan(run, kLong, out.string(), "");
  auto procs = start_all(run, processes);
  ASSERT_TRUE(wait_until(
      [&] {
        const auto s = summary_of(out);
        return !s.is_null() && s["recorded_up_to_frame"].get<long>() >= 100;
      },
      30))
      << "summary.json never got past frame 100\n" << read_file(out / "summary.json")
      << describe_logs(procs);
  Process& recorder = *procs[member_index(processes, "recorder")];
  recorder.signal(SIGKILL);
  ASSERT_TRUE(recorder.wait(10).has_value());
  const auto summary = summary_of(out);
  ASSERT_FALSE(summary.is_null());
  EXPECT_EQ(summary["status"], "running");
  const long recorded = summary["recorded_up_to_frame"].get<long>();
  const auto rows = rows_per_frame(out);
  ASSERT_TRUE(rows.contains(recorded));
  for (long f = 0; f <= recorded; ++f) EXPECT_EQ(rows.at(f), 3) << "frame " << f;
  wait_all(procs, 40.0);  // the coordinator aborts the run without its recorder
}

// Before: frames 0 and final_frame -1 after a lost coordinator, whatever was recorded.
TEST(RecorderFailure, AKilledCoordinatorLeavesTheRecordersCount) {
  TestRun run;
  const fs::path out = run.dir / "out";
  const auto processes = plan(run, kLong, out.string(), "");
  auto procs = start_all(run, processes);
  // Frames 0..99 recorded (3 vehicles, a header).
  ASSERT_TRUE(wait_until([&] { return count_lines(read_file(out / "vehicles.csv")) > 300; }, 30))
      << describe_logs(procs);
  procs[member_index(processes, "coordinator")]->signal(SIGKILL);
  Process& recorder = *procs[member_index(processes, "recorder")];
  const auto code = recorder.wait(60);
  ASSERT_TRUE(code.has_value()) << describe_logs(procs);
  const auto summary = summary_of(out);
  ASSERT_FALSE(summary.is_null());
  EXPECT_EQ(summary["status"], "aborted");
  EXPECT_EQ(summary["stats_missing"], true) << summary.dump(2);
  const long recorded = summary["recorded_up_to_frame"].get<long>();
  EXPECT_GE(recorded, 99);
  EXPECT_EQ(summary["final_frame"].get<long>(), recorded);
  EXPECT_EQ(summary["frames"].get<long>(), recorded + 1);
  EXPECT_EQ(rows_per_frame(out).rbegin()->first, recorded);
  wait_all(procs, 40.0);
}
