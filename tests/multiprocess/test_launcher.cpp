// The launcher (launch_scripts/run_scenario.sh) as a user runs it: run ids and output folders of
// its own, refusing what the machine cannot start, ending a run that cannot start at once, and
// saying plainly when the run completed but its recording did not.
#include <nlohmann/json.hpp>
#include <sched.h>

#include <regex>

#include "harness.hpp"

namespace syndds::test {
namespace {

const std::string kScenarios = kSource + "/tests/multiprocess/scenarios/";
const std::string kLauncher = kSource + "/launch_scripts/run_scenario.sh";

/// A bin folder with the real programs, except `fakes` (program name -> shell script body).
fs::path bin_with_fakes(const TestRun& run, const std::map<std::string, std::string>& fakes) {
  const fs::path bin = run.dir / "build" / "bin";
  fs::create_directories(bin);
  for (const auto& entry : fs::directory_iterator(kBin)) {
    const std::string name = entry.path().filename().string();
    if (fakes.contains(name)) continue;
    fs::create_symlink(entry.path(), bin / name);
  }
  for (const auto& [name, body] : fakes) {
    std::ofstream(bin / name) << "#!/bin/sh\n" << body << "\n";
    fs::permissions(bin / name, fs::perms::owner_all, fs::perm_options::add);
  }
  return bin;
}

/// The launcher in `cwd` with `args`; its programs from `build` (the folder holding bin/).
std::unique_ptr<Process> launch(const TestRun& run, const fs::path& cwd, const std::string& args,
                                const std::string& log_name, const std::string& env = "",
                                const fs::path& build = fs::path(kBin) / "..") {
  return std::make_unique<Process>("env -C " + cwd.string() + " SYNDDS_BUILD_DIR=" +
                                       build.string() + " " + env + " " + kLauncher + " " + args,
                                   run.dir / log_name);
}

// A scenario file with a long name still gets a run id every process accepts (at most 64
// characters), and the run completes.
TEST(Launcher, LongScenarioNameGivesAValidRunId) {
  TestRun run;
  const std::string stem(60, 'x');
  const fs::path scenario = run.dir / (stem + "_two_vehicles.yaml");
  fs::copy_file(kScenarios + "two_vehicles.yaml", scenario);
  auto launcher = launch(run, run.dir,
                         scenario.string() + " --duration 0.3 --domain " +
                             std::to_string(run.domain) + " --output " + (run.dir / "out").string(),
                         "launcher.log");
  const auto code = launcher->wait(90);
  ASSERT_TRUE(code.has_value()) << launcher->log();
  EXPECT_EQ(*code, 0) << launcher->log();
  std::smatch m;
  const std::string log = launcher->log();
  ASSERT_TRUE(std::regex_search(log, m, std::regex("for run (\\S+) ")));
  EXPECT_LE(m[1].str().size(), 64u) << m[1];
}

// Two launches of one scenario in the same second get their own output folder and run id.
TEST(Launcher, LaunchesInTheSameSecondDoNotShareAFolder) {
  TestRun run;
  const std::string scenario = kScenarios + "two_vehicles.yaml";
  for (int attempt = 0; attempt < 5; ++attempt) {
    auto a = launch(run, run.dir, scenario + " --print-commands", "a.log");
    auto b = launch(run, run.dir, scenario + " --print-commands", "b.log");
    ASSERT_EQ(a->wait(30), 0) << a->log();
    ASSERT_EQ(b->wait(30), 0) << b->log();
    const std::regex output_re("--output (\\S*runs/\\S+-(\\d{8}-\\d{6})\\S*)");
    const std::regex run_re("--run-id (\\S+)");
    std::smatch ma, mb, ra, rb;
    const std::string la = a->log(), lb = b->log();
    ASSERT_TRUE(std::regex_search(la, ma, output_re)) << la;
    ASSERT_TRUE(std::regex_search(lb, mb, output_re)) << lb;
    if (ma[2] != mb[2]) continue;  // the second changed between the two: try again
    EXPECT_NE(ma[1], mb[1]);
    ASSERT_TRUE(std::regex_search(la, ra, run_re));
    ASSERT_TRUE(std::regex_search(lb, rb, run_re));
    EXPECT_NE(ra[1], rb[1]);
    return;
  }
  FAIL() << "no two launches within one second in 5 attempts";
}

// A member that exits before it joined can never join: the launcher ends the run at once and
// names it, instead of waiting out the coordinator's join timeout (60 s in this scenario).
TEST(Launcher, MemberThatExitsBeforeJoiningEndsTheRunAtOnce) {
  TestRun run;
  const fs::path scenario = run.dir / "slow_join.yaml";
  std::string text = read_file(kScenarios + "two_vehicles.yaml");
  text = std::regex_replace(text, std::regex("join_timeout_s: 20"), "join_timeout_s: 60");
  std::ofstream(scenario) << text;
  const fs::path bin = bin_with_fakes(
      run, {{"syndds_vehicle", "echo \"error: this vehicle cannot start\" >&2; exit 3"}});
  auto launcher = launch(run, run.dir,
                         scenario.string() + run.common_args() + " --output " +
                             (run.dir / "out").string(),
                         "launcher.log", "", bin.parent_path());
  const auto code = launcher->wait(40);
  ASSERT_TRUE(code.has_value()) << "still waiting for the join timeout\n" << launcher->log();
  EXPECT_EQ(*code, 2) << launcher->log();
  const std::string log = launcher->log();
  EXPECT_NE(log.find("exited (status 3) before the run started"), std::string::npos) << log;
  EXPECT_NE(log.find("this vehicle cannot start"), std::string::npos) << log;
  for (const auto& [member, pid] : launched_pids(run.dir / "out")) {
    EXPECT_NE(::kill(pid, 0), 0) << member << " still runs";
  }
}

// Once the run has ended, the launcher starts nothing more: here the coordinator fails at once
// and 30 vehicles with their controllers and the recorder (62 processes) are to be started.
TEST(Launcher, StopsStartingOnceTheRunHasEnded) {
  TestRun run;
  const fs::path scenario = run.dir / "many.yaml";
  std::ofstream s(scenario);
  s << "name: many\ntime: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1.0}\nvehicles:\n";
  for (int i = 0; i < 30; ++i) {
    s << "  - id: v" << i << "\n    model: hmmwv\n    controller: {type: path_follower, path: "
      << "{waypoints: [[0, " << 10 * i << "], [50, " << 10 * i << "]]}, speed: {target_mps: 2}}\n";
  }
  s.close();
  const fs::path bin = bin_with_fakes(run, {{"syndds_coordinator", "exit 1"},
                                            {"syndds_vehicle", "exec sleep 60"},
                                            {"syndds_controller", "exec sleep 60"}});
  auto launcher = launch(run, run.dir,
                         scenario.string() + run.common_args() + " --output " +
                             (run.dir / "out").string(),
                         "launcher.log", "SYNDDS_PROCESS_MB=1 SYNDDS_LAUNCH_GRACE_S=2",
                         bin.parent_path());
  const auto code = launcher->wait(60);
  ASSERT_TRUE(code.has_value()) << launcher->log();
  EXPECT_NE(*code, 0) << launcher->log();
  const auto started = launched_pids(run.dir / "out");
  EXPECT_LT(started.size(), 62u) << launcher->log();
  EXPECT_NE(launcher->log().find("were not started"), std::string::npos) << launcher->log();
  for (const auto& [member, pid] : started) EXPECT_NE(::kill(pid, 0), 0) << member << " runs";
}

// The launcher refuses a run that needs more memory than the machine has, before starting
// anything (here: each process said to need 100 TB).
TEST(Launcher, RefusesWhatTheMachineCannotStart) {
  TestRun run;
  auto launcher = launch(run, run.dir,
                         kScenarios + "two_vehicles.yaml" + run.common_args() + " --output " +
                             (run.dir / "out").string(),
                         "launcher.log", "SYNDDS_PROCESS_MB=100000000");
  const auto code = launcher->wait(30);
  ASSERT_TRUE(code.has_value()) << launcher->log();
  EXPECT_EQ(*code, 1) << launcher->log();
  EXPECT_NE(launcher->log().find("MB available"), std::string::npos) << launcher->log();
  EXPECT_FALSE(fs::exists(run.dir / "out" / "logs" / "pids"));
}

// A group process (a vehicle with its controller) is counted at SYNDDS_GROUP_MB, not at the
// single-member process's 100 MB.
TEST(Launcher, CountsGroupProcessesAtTheirOwnSize) {
  TestRun run;
  auto launcher = launch(run, run.dir,
                         kScenarios + "two_vehicles.yaml" + run.common_args() + " --output " +
                             (run.dir / "out").string() + " --processes per_vehicle",
                         "launcher.log", "SYNDDS_GROUP_MB=100000000");
  const auto code = launcher->wait(30);
  ASSERT_TRUE(code.has_value()) << launcher->log();
  EXPECT_EQ(*code, 1) << launcher->log();
  EXPECT_NE(launcher->log().find("100000000 MB a group process"), std::string::npos)
      << launcher->log();
  EXPECT_FALSE(fs::exists(run.dir / "out" / "logs" / "pids"));
}

// on_member_loss: continue keeps the run going without a killed recorder; the coordinator
// completes it, and the launcher says that the run completed but its recording did not (exit 2:
// the results are incomplete).
TEST(Launcher, KilledRecorderIsReportedAsAnIncompleteRecording) {
  TestRun run;
  const fs::path out = run.dir / "out";
  auto launcher = start_launcher(run, kScenarios + "continue_run.yaml");
  ASSERT_TRUE(wait_until([&] { return count_lines(read_file(out / "vehicles.csv")) > 100; }, 30))
      << launcher->log();
  const int pid = launched_pid(out, "recorder");
  ASSERT_NE(pid, 0);
  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  const auto code = launcher->wait(40);
  ASSERT_TRUE(code.has_value()) << launcher->log();
  EXPECT_EQ(*code, 2) << launcher->log();
  EXPECT_NE(launcher->log().find("the run completed but the recording is incomplete: recorder "
                                 "was killed by signal 9"),
            std::string::npos)
      << launcher->log();
  EXPECT_NE(read_file(out / "logs" / "coordinator.log").find("run completed"), std::string::npos);
}

/// The scheduling policy of every thread of process `pid` (Linux's sched_getscheduler takes a
/// thread id), or empty if it is gone.
std::vector<int> thread_policies(int pid) {
  std::vector<int> out;
  std::error_code ec;
  for (const auto& task : fs::directory_iterator(fs::path("/proc") / std::to_string(pid) / "task", ec)) {
    const int policy = sched_getscheduler(std::stoi(task.path().filename().string()));
    if (policy >= 0) out.push_back(policy);
  }
  return out;
}

// Members run SCHED_BATCH (services' --cpu-policy, default batch): every thread, also those Fast
// DDS starts after the policy was set, so a woken member does not preempt the one that woke it.
TEST(Launcher, MembersAndTheirDdsThreadsRunAsBatch) {
  TestRun run;
  const fs::path out = run.dir / "out";
  auto launcher = start_launcher(run, kScenarios + "continue_run.yaml");
  ASSERT_TRUE(wait_until([&] { return count_lines(read_file(out / "vehicles.csv")) > 10; }, 30))
      << launcher->log();
  for (const std::string member : {"coordinator", "recorder"}) {
    const int pid = launched_pid(out, member);
    ASSERT_NE(pid, 0) << member;
    const auto policies = thread_policies(pid);
    ASSERT_GE(policies.size(), 5u) << member << ": the main thread and Fast DDS's";
    for (const int p : policies) EXPECT_EQ(p, SCHED_BATCH) << member;
  }
  EXPECT_EQ(launcher->wait(40), std::optional<int>(0)) << launcher->log();
}

}  // namespace
// DDS Security with every member of the default scenario: 9 secure participants start at once,
// every pair authenticates, and the run gives the plain single-process run's vehicles.csv. On
// Fast DDS 2.9.1 without the lock of services/dds/fastdds_security_race.cpp about half of these
// runs lost a pair of participants for good (join timeout, or "announced inputs missing").
TEST(Launcher, DefaultScenarioRunsWithDdsSecurity) {
  TestRun run;
  const fs::path security = run.dir / "security";
  const std::string scenario = kConfig + "/scenarios/default.yaml";
  const std::string make = "env SYNDDS_BUILD_DIR=" + kBin + "/.. " + kSource +
                           "/launch_scripts/make_security.sh " + scenario + " --output " +
                           security.string() + " > " + (run.dir / "make_security.log").string() +
                           " 2>&1";
  ASSERT_EQ(std::system(make.c_str()), 0) << read_file(run.dir / "make_security.log");
  // 15 s simulated: a pair that exchanges nothing has time to finish its handshake (a first
  // message sent before the peer knew the sender is resent a second later).
  auto launcher = start_launcher(
      run, scenario, "--duration 15 --log-level debug --security-dir " + security.string());
  const auto code = launcher->wait(150);
  ASSERT_TRUE(code.has_value()) << launcher->log();
  ASSERT_EQ(*code, 0) << launcher->log();
  // Each process authenticated each of the 8 others (the participant listener's debug line).
  for (const auto& [member, pid] : launched_pids(run.dir / "out")) {
    const std::string log = read_file(run.dir / "out" / "logs" / log_name(member));
    std::size_t authenticated = 0;
    for (std::size_t at = 0; (at = log.find(" authenticated\n", at)) != std::string::npos; ++at) {
      ++authenticated;
    }
    EXPECT_EQ(authenticated, 8u) << member;
  }
  EXPECT_EQ(read_file(run.dir / "out" / "vehicles.csv"),
            single_process_csv(run, scenario, "--duration 15"));
}

// Soil routing under DDS Security: the permissions let a vehicle and the recorder write the
// ruts addressed to another vehicle (terrain_patch, in that vehicle's partition) and the
// recorder the snapshot; the routed scm_rut, every member authenticated, gives the plain
// single-process run's vehicles.csv (without that rule the patch writers are refused).
TEST(Launcher, SoilRoutingRunsWithDdsSecurity) {
  TestRun run;
  const std::string plain = kSource + "/tests/multiprocess/scenarios/scm_rut.yaml";
  const std::string scenario = routed_copy(plain, run.dir);
  const fs::path security = run.dir / "security";
  const std::string make = "env SYNDDS_BUILD_DIR=" + kBin + "/.. " + kSource +
                           "/launch_scripts/make_security.sh " + scenario + " --output " +
                           security.string() + " > " + (run.dir / "make_security.log").string() +
                           " 2>&1";
  ASSERT_EQ(std::system(make.c_str()), 0) << read_file(run.dir / "make_security.log");
  auto launcher = start_launcher(run, scenario, "--security-dir " + security.string());
  const auto code = launcher->wait(150);
  ASSERT_TRUE(code.has_value()) << launcher->log();
  ASSERT_EQ(*code, 0) << launcher->log();
  EXPECT_EQ(read_file(run.dir / "out" / "vehicles.csv"),
            single_process_csv(run, plain, ""));
}

// --resume RUN_DIR alone starts the run with the scenario and options in RUN_DIR/launch.args;
// options typed with it replace recorded ones, a scenario typed before it the recorded one.
TEST(Launcher, AResumeTakesTheRecordedScenarioAndOptionsUnlessTyped) {
  TestRun run;
  const fs::path dir = run.dir / "old";
  fs::create_directories(dir / "checkpoints");
  const std::string scenario = kScenarios + "two_vehicles.yaml";
  std::ofstream(dir / "launch.args") << scenario << "\n--duration\n4.5\n--realtime\n--domain\n7\n"
                                     << "--config-dir\n"
                                     << kConfig << "\n";
  auto printed = [&](const std::string& args) {
    auto launcher = launch(run, run.dir, args + " --single-process --print-commands", "print.log");
    EXPECT_EQ(launcher->wait(30), 0) << launcher->log();
    return launcher->log();
  };
  std::string line = printed("--resume " + dir.string());
  EXPECT_NE(line.find("syndds_sim " + scenario + " --output " + dir.string()), std::string::npos)
      << line;
  EXPECT_NE(line.find(" --duration 4.5 --realtime --domain 7 --config-dir " + kConfig +
                      " --resume-from latest"),
            std::string::npos)
      << line;
  line = printed("--resume " + dir.string() + " --domain 9 --from-frame 300");
  for (const std::string want :
       {" --domain 9 ", " --duration 4.5 ", " --realtime ", " --resume-from 300"}) {
    EXPECT_NE(line.find(want), std::string::npos) << want << " in " << line;
  }
  EXPECT_EQ(line.find("--domain 7"), std::string::npos) << line;
  const std::string other = kScenarios + "checkpointed.yaml";
  line = printed(other + " --resume " + dir.string());
  EXPECT_NE(line.find("syndds_sim " + other + " "), std::string::npos) << line;
  EXPECT_NE(line.find(" --duration 4.5 "), std::string::npos) << line;
}

// A run directory without launch.args (a run not started by the launcher) needs the scenario:
// the launcher says so instead of guessing.
TEST(Launcher, AResumeWithoutARecordedLaunchAsksForTheScenario) {
  TestRun run;
  const fs::path dir = run.dir / "old";
  fs::create_directories(dir / "checkpoints");
  auto launcher = launch(run, run.dir, "--resume " + dir.string(), "launcher.log");
  EXPECT_EQ(launcher->wait(30), 1) << launcher->log();
  const std::string log = launcher->log();
  EXPECT_NE(log.find("--resume " + dir.string() + ": no launch.args there"), std::string::npos)
      << log;
  EXPECT_NE(log.find("run_scenario.sh SCENARIO.yaml --resume " + dir.string()), std::string::npos)
      << log;
}

// A run the launcher starts records what --resume needs: the scenario's absolute path (the
// resume may be typed in another folder) and the options, paths made absolute.
TEST(Launcher, ARunRecordsItsScenarioAndOptions) {
  TestRun run;
  const fs::path cwd = run.dir / "cwd";
  fs::create_directories(cwd / "scenarios");
  fs::copy_file(kScenarios + "two_vehicles.yaml", cwd / "scenarios" / "two.yaml");
  fs::create_directory_symlink(kConfig, cwd / "config");
  auto launcher = launch(
      run, cwd,
      "scenarios/two.yaml --duration 0.3 --config-dir config --output out" + run.common_args(),
      "launcher.log");
  ASSERT_EQ(launcher->wait(90), 0) << launcher->log();
  const fs::path real = fs::canonical(cwd);
  EXPECT_EQ(read_file(cwd / "out" / "launch.args"),
            (real / "scenarios" / "two.yaml").string() + "\n--duration\n0.3\n--config-dir\n" +
                (real / "config").string() + "\n--domain\n" + std::to_string(run.domain) +
                "\n--run-id\n" + run.run_id + "\n");
}

}  // namespace syndds::test
