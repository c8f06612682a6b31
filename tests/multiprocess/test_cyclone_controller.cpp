// The CycloneDDS example controller (examples/cyclone_controller, C on CycloneDDS) as the
// external controller of a real run: the coordinator, vehicle and recorder are the Fast DDS
// programs, the controller talks to them over UDP from another DDS implementation.
#include <nlohmann/json.hpp>

#include <cmath>

#include "harness.hpp"

using namespace syndds::test;

namespace {

const std::string kController = kBin + "/syndds_cyclone_controller";
const std::string kScenario = kSource + "/tests/multiprocess/scenarios/cyclone_external.yaml";

// The path given to the controller (it is not in the scenario) and its end.
constexpr double kPath[][2] = {{0, 0}, {20, 0}, {35, 15}};
constexpr std::size_t kPathPoints = sizeof kPath / sizeof kPath[0];

std::string controller_command(const TestRun& run) {
  return kController + run.common_args() +
         " --vehicle cy --waypoints '0,0;20,0;35,15' --speed 5 --interface lo";
}

double distance_to_path(double x, double y) {
  double best = 1e9;
  for (std::size_t i = 0; i + 1 < kPathPoints; ++i) {
    const double ax = kPath[i][0], ay = kPath[i][1];
    const double dx = kPath[i + 1][0] - ax, dy = kPath[i + 1][1] - ay;
    const double t = std::clamp(((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy), 0.0, 1.0);
    best = std::min(best, std::hypot(ax + t * dx - x, ay + t * dy - y));
  }
  return best;
}

struct Row {
  long frame;
  double x, y, speed;
};

std::vector<Row> rows_of(const std::string& csv) {
  std::vector<Row> rows;
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    const auto f = split_csv(line);
    if (f.size() < 14 || f[2] != "cy") continue;
    rows.push_back({std::stol(f[0]), std::stod(f[3]), std::stod(f[4]), std::stod(f[13])});
  }
  return rows;
}

// One run with syndds_plan's processes plus the CycloneDDS controller; returns vehicles.csv.
std::string run_once(const TestRun& run, const std::string& name, const std::string& extra = "") {
  const fs::path out = run.dir / name;
  auto processes = plan(run, kScenario, out.string(), extra);
  processes.push_back({"external/cy", controller_command(run)});
  std::vector<std::unique_ptr<Process>> procs;
  for (const auto& p : processes) {
    procs.push_back(std::make_unique<Process>(p.command, run.dir / (name + "-" + log_name(p.member))));
  }
  const auto codes = wait_all(procs, 60.0);
  for (std::size_t i = 0; i < codes.size(); ++i) {
    EXPECT_EQ(codes[i], 0) << processes[i].member << "\n" << describe_logs(procs);
  }
  return read_file(out / "vehicles.csv");
}

// The controller is a build dependency of this test binary: missing, it is a failure.
void require_controller() { ASSERT_TRUE(fs::exists(kController)) << kController << " not built"; }

}  // namespace

// The controller drives the vehicle along its path to the end, where it stops; every command
// it sent was accepted; a second run gives the same trajectory byte for byte.
TEST(CycloneController, DrivesAlongItsPathAndRunsAreIdentical) {
  ASSERT_NO_FATAL_FAILURE(require_controller());
  TestRun run;
  const std::string first = run_once(run, "first");
  const auto rows = rows_of(first);
  ASSERT_EQ(rows.size(), 1401u) << first.substr(0, 2000);  // frames 0..1400

  double max_off_path = 0.0, max_speed = 0.0;
  for (const auto& r : rows) {
    max_off_path = std::max(max_off_path, distance_to_path(r.x, r.y));
    max_speed = std::max(max_speed, r.speed);
  }
  const Row& last = rows.back();
  std::printf("cyclone controller: end at (%.2f, %.2f), %.2f m from the path's end; "
              "max %.2f m off the path; top speed %.2f m/s\n",
              last.x, last.y, std::hypot(last.x - 35.0, last.y - 15.0), max_off_path, max_speed);
  EXPECT_LT(std::hypot(last.x - 35.0, last.y - 15.0), 2.0);  // stopped at the end of its path
  EXPECT_LT(std::abs(last.speed), 0.2);
  EXPECT_LT(max_off_path, 1.5);  // followed it (the 45 degree corner is cut a little)
  EXPECT_GT(max_speed, 4.0);     // at about the requested 5 m/s
  EXPECT_LT(max_speed, 6.0);

  // Every command came from external/cy and none was rejected by the vehicle.
  std::istringstream commands(read_file(run.dir / "first" / "commands.csv"));
  std::string line;
  std::getline(commands, line);
  std::size_t count = 0;
  while (std::getline(commands, line)) {
    const auto f = split_csv(line);
    ASSERT_GE(f.size(), 8u) << line;
    EXPECT_EQ(f[3], "external/cy") << line;
    EXPECT_EQ(f[7], "0") << line;
    ++count;
  }
  EXPECT_EQ(count, 1400u);  // frames 1..1400: there is no state to steer by in frame 0
  const auto summary = nlohmann::json::parse(read_file(run.dir / "first" / "summary.json"));
  EXPECT_EQ(summary["status"], "completed");

  EXPECT_EQ(run_once(run, "second"), first);
}

// kill -9 of the controller: its 2 s participant lease expires, the coordinator names it lost
// and aborts; the launcher exits 2.
TEST(CycloneController, KilledControllerIsNamedLostWithinThreeSeconds) {
  ASSERT_NO_FATAL_FAILURE(require_controller());
  TestRun run;
  const fs::path out = run.dir / "out";
  // The launcher of this build (not the default build/ folder), with a longer run.
  const std::string build_dir = fs::path(kBin).parent_path().string();
  Process launcher("env SYNDDS_BUILD_DIR=" + build_dir + " " + kSource +
                       "/launch_scripts/run_scenario.sh " + kScenario + " --output " +
                       out.string() + " --duration 60" + run.common_args(),
                   run.dir / "launcher.log");
  Process controller(controller_command(run), run.dir / "cyclone.log");
  // Well into the run (100 frames recorded), kill the controller.
  ASSERT_TRUE(wait_until([&] { return count_lines(read_file(out / "vehicles.csv")) > 100; }, 30))
      << launcher.log() << controller.log();
  controller.signal(SIGKILL);
  const auto t_kill = Clock::now();
  ASSERT_TRUE(controller.wait(5).has_value());

  const fs::path coordinator_log = out / "logs" / "coordinator.log";
  const bool named = wait_until(
      [&] {
        return read_file(coordinator_log).find("member external/cy lost") != std::string::npos;
      },
      15);
  const double detected_s = std::chrono::duration<double>(Clock::now() - t_kill).count();
  ASSERT_TRUE(named) << read_file(coordinator_log);
  std::printf("kill -9 of the cyclone controller to the coordinator naming it lost: %.2f s\n",
              detected_s);
  EXPECT_LT(detected_s, 3.0);
  EXPECT_NE(read_file(coordinator_log)
                .find("run aborted: member external/cy lost: its process exited"),
            std::string::npos)
      << read_file(coordinator_log);

  const auto code = launcher.wait(40);
  ASSERT_TRUE(code.has_value()) << launcher.log();
  EXPECT_EQ(*code, 2) << launcher.log();
  EXPECT_NE(launcher.log().find("aborted: member external/cy lost"), std::string::npos)
      << launcher.log();
}

// A second copy of the controller (same member id, its own participant) joins the run under
// way. The coordinator refuses it (docs/protocol.md, "Admission"): the copy exits 4 having
// written nothing, the refusal is an intrusion in events.csv and summary.json, and the run
// completes byte-identical to an undisturbed one. Before admission existed the copy acted on
// the replayed grants, reported "grant of frame N skips frame 0" and the run aborted.
TEST(CycloneController, ASecondCopyJoiningMidRunIsRefusedAndChangesNothing) {
  ASSERT_NO_FATAL_FAILURE(require_controller());
  TestRun run;
  // Paced to the wall clock (6 s), so that the copy surely comes while the run goes on.
  const std::string paced = "--realtime --duration 6";
  const std::string undisturbed = run_once(run, "undisturbed", paced);

  const fs::path out = run.dir / "disturbed";
  auto processes = plan(run, kScenario, out.string(), paced);
  processes.push_back({"external/cy", controller_command(run)});
  std::vector<std::unique_ptr<Process>> procs;
  for (const auto& p : processes) {
    procs.push_back(std::make_unique<Process>(p.command, run.dir / ("disturbed-" + log_name(p.member))));
  }
  ASSERT_TRUE(wait_until([&] { return count_lines(read_file(out / "vehicles.csv")) > 100; }, 30))
      << describe_logs(procs);
  Process copy(controller_command(run), run.dir / "copy.log");
  const auto copy_code = copy.wait(30);
  ASSERT_TRUE(copy_code.has_value()) << copy.log();
  EXPECT_EQ(*copy_code, 4) << copy.log();
  EXPECT_NE(copy.log().find("error: refused by the coordinator as external/cy: participant "),
            std::string::npos)
      << copy.log();

  const auto codes = wait_all(procs, 60.0);
  for (std::size_t i = 0; i < codes.size(); ++i) {
    EXPECT_EQ(codes[i], 0) << processes[i].member << "\n" << describe_logs(procs);
  }
  EXPECT_EQ(read_file(out / "vehicles.csv"), undisturbed);

  // The copy's claim is an intrusion: in the coordinator's log, events.csv and summary.json.
  EXPECT_NE(read_file(run.dir / ("disturbed-" + log_name("coordinator"))).find("intrusion: participant "),
            std::string::npos);
  const std::string events = read_file(out / "events.csv");
  EXPECT_NE(events.find(",intrusion,cy,participant "), std::string::npos) << events;
  const auto summary = nlohmann::json::parse(read_file(out / "summary.json"));
  EXPECT_EQ(summary["status"], "completed");
  ASSERT_EQ(summary["intrusions"].size(), 1u) << summary.dump(2);
  EXPECT_EQ(summary["intrusions"][0]["member"], "external/cy");
  EXPECT_NE(summary["intrusions"][0]["what"].get<std::string>().find("claimed the member"),
            std::string::npos);
  EXPECT_LT(summary["intrusions"][0]["frame"].get<int>(), 600);  // during the run
  // Every command came from the first copy and none was rejected.
  std::istringstream commands(read_file(out / "commands.csv"));
  std::string line;
  std::getline(commands, line);
  std::size_t count = 0;
  while (std::getline(commands, line)) ++count;
  EXPECT_EQ(count, 600u);
}

// on_member_loss: recover with the controller's own checkpoints (--checkpoint-dir): killed
// with -9 mid-run and restarted with --rejoin, it rolls back with every other member to the
// last checkpoint, and the run ends byte-identical to an undisturbed one.
TEST(CycloneController, KilledAndRestartedUnderRecoverEndsByteIdentical) {
  ASSERT_NO_FATAL_FAILURE(require_controller());
  TestRun run;
  const std::string scenario = kSource + "/tests/multiprocess/scenarios/cyclone_recover.yaml";
  const std::string paced = "--realtime";  // 6 s: time to kill and restart mid-run
  auto start = [&](const std::string& name, std::vector<Planned>& processes) {
    processes = plan(run, scenario, (run.dir / name).string(), paced);
    std::vector<std::unique_ptr<Process>> procs;
    for (const auto& p : processes) {
      procs.push_back(std::make_unique<Process>(p.command, run.dir / (name + "-" + log_name(p.member))));
    }
    return procs;
  };
  auto controller = [&](const std::string& name, const std::string& extra) {
    fs::create_directories(run.dir / (name + "-state"));
    return controller_command(run) + " --checkpoint-dir " + (run.dir / (name + "-state")).string() +
           extra;
  };

  std::vector<Planned> processes;
  auto procs = start("undisturbed", processes);
  Process first(controller("undisturbed", ""), run.dir / "undisturbed-cyclone.log");
  for (auto code : wait_all(procs, 60)) EXPECT_EQ(code, 0) << describe_logs(procs);
  EXPECT_EQ(first.wait(20), 0) << first.log();
  const std::string undisturbed = read_file(run.dir / "undisturbed" / "vehicles.csv");
  ASSERT_EQ(count_lines(undisturbed), 602u);
  // Its checkpoints, one a second (frames 100 ... 500).
  EXPECT_TRUE(fs::exists(run.dir / "undisturbed-state" / "external_cy-300.state"));

  procs = start("disturbed", processes);
  const fs::path out = run.dir / "disturbed";
  auto victim = std::make_unique<Process>(controller("disturbed", ""), run.dir / "victim.log");
  // Past the checkpoint of frame 200 (the coordinator declared it complete).
  ASSERT_TRUE(wait_until([&] { return fs::exists(out / "checkpoints" / "frame_000000200" / "complete.yaml") &&
                                      count_lines(read_file(out / "vehicles.csv")) > 250; }, 30))
      << describe_logs(procs) << victim->log();
  victim->signal(SIGKILL);
  ASSERT_TRUE(victim->wait(5).has_value());
  Process restarted(controller("disturbed", " --rejoin"), run.dir / "restarted.log");
  for (auto code : wait_all(procs, 60)) EXPECT_EQ(code, 0) << describe_logs(procs) << restarted.log();
  EXPECT_EQ(restarted.wait(20), 0) << restarted.log();
  EXPECT_NE(restarted.log().find("rolled back to the checkpoint of frame "), std::string::npos)
      << restarted.log();
  EXPECT_EQ(read_file(out / "vehicles.csv"), undisturbed);
  const std::string recoveries = read_file(out / "recoveries.csv");
  EXPECT_NE(recoveries.find(",external/cy,\"its process exited\""), std::string::npos) << recoveries;
}

// kill -9 of the coordinator: the controller, on the same machine, watches the coordinator's
// process (its announced process_key) and exits 3 saying so within 2 s, as every syndds member
// does; elsewhere the coordinator's 10 s DDS lease would tell.
TEST(CycloneController, ExitsWithStatus3WhenTheCoordinatorIsLost) {
  ASSERT_NO_FATAL_FAILURE(require_controller());
  TestRun run;
  const fs::path out = run.dir / "out";
  auto processes = plan(run, kScenario, out.string(), "--duration 60");
  ASSERT_EQ(processes[0].member, "coordinator");
  auto procs = start_all(run, processes);
  Process controller(controller_command(run), run.dir / "cyclone.log");
  ASSERT_TRUE(wait_until([&] { return count_lines(read_file(out / "vehicles.csv")) > 100; }, 30))
      << describe_logs(procs) << controller.log();
  procs[0]->signal(SIGKILL);
  const auto t_kill = Clock::now();
  const auto code = controller.wait(20);
  const double exit_s = std::chrono::duration<double>(Clock::now() - t_kill).count();
  ASSERT_TRUE(code.has_value()) << controller.log();
  EXPECT_EQ(*code, 3) << controller.log();
  std::printf("kill -9 of the coordinator to the cyclone controller's exit: %.2f s\n", exit_s);
  EXPECT_LT(exit_s, 2.0) << controller.log();
  EXPECT_NE(controller.log().find("error: the coordinator was lost"), std::string::npos)
      << controller.log();
  wait_all(procs, 20);
}

// Bad command lines are refused before any DDS work, naming the option, with status 1.
TEST(CycloneController, BadCommandLinesNameTheOption) {
  ASSERT_NO_FATAL_FAILURE(require_controller());
  TestRun run;
  const std::string base = kController + " --domain 1 --run-id r --vehicle cy";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {base + " --waypoints '0,0;10'", "--waypoints: point 2: expected ','"},
      {base + " --waypoints '0,0;0,0'", "--waypoints: point 2 repeats point 1"},
      {base + " --waypoints '0,0;10,0' --speed fast", "--speed: expected a number, got \"fast\""},
      {base + " --waypoints '0,0;10,0' --speed -2", "--speed: must be between 0.1 and 30"},
      {kController + " --run-id r --vehicle cy --waypoints '0,0;1,0'", "--domain: is required"},
      {base, "--waypoints: is required"},
      {base + " --waypoints '0,0;10,0' --sped 3", "--sped: unknown option"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    Process p(cases[i].first, run.dir / ("cli" + std::to_string(i) + ".log"));
    const auto code = p.wait(10);
    ASSERT_TRUE(code.has_value()) << cases[i].first;
    EXPECT_EQ(*code, 1) << cases[i].first << "\n" << p.log();
    EXPECT_NE(p.log().find(cases[i].second), std::string::npos) << cases[i].first << "\n" << p.log();
  }
}
