// How runs end: signals, an interrupt that must not lose the last complete frame, a late member
// that is refused without harming the run, a member that fails after the run completed.
#include <nlohmann/json.hpp>

#include <atomic>
#include <map>
#include <thread>

#include "dds/coordinator_service.hpp"
#include "dds/member_runtime.hpp"
#include "harness.hpp"
#include "../protocol/test_agents.hpp"

using namespace syndds;
using namespace syndds::test;
namespace sdds = syndds::dds;

namespace {

const std::string kLongRun = kSource + "/tests/multiprocess/scenarios/long_run.yaml";
const std::string kLateCamera = kSource + "/tests/multiprocess/scenarios/late_camera.yaml";

std::size_t index_of(const std::vector<Planned>& processes, const std::string& member) {
  for (std::size_t i = 0; i < processes.size(); ++i) {
    if (processes[i].member == member) return i;
  }
  throw std::runtime_error("no process for " + member);
}

}  // namespace

// A launcher's terminal that closes sends SIGHUP: the run ends as on Ctrl-C, and the summary
// says so (before, the process died where it stood and the summary still said "running").
TEST(Signals, HangUpEndsTheRunLikeAnInterrupt) {
  TestRun run;
  const fs::path out = run.dir / "single";
  Process sim(kBin + "/syndds_sim " + kLongRun + " --quiet --output " + out.string(),
              run.dir / "sim.log");
  ASSERT_TRUE(wait_until([&] { return count_lines(read_file(out / "vehicles.csv")) > 30; }, 30))
      << sim.log();
  sim.signal(SIGHUP);
  const auto code = sim.wait(20);
  ASSERT_TRUE(code.has_value()) << sim.log();
  EXPECT_EQ(*code, 130) << sim.log();
  const std::string summary = read_file(out / "summary.txt");
  EXPECT_NE(summary.find("aborted: interrupted"), std::string::npos) << summary;
}

// Ctrl-C reaches the recorder and the coordinator (one terminal), the recorder first. The
// recorder waits for the coordinator's verdict, so it keeps the last frame every member
// completed and records the coordinator's reason (before, it aborted at once on its own and its
// summary named no final frame).
TEST(Interrupt, RecorderKeepsTheLastCompleteFrame) {
  TestRun run;
  const fs::path out = run.dir / "out";
  auto processes = plan(run, kLongRun, out.string(), "");
  auto procs = start_all(run, processes);
  ASSERT_TRUE(wait_until([&] { return count_lines(read_file(out / "vehicles.csv")) > 90; }, 30))
      << describe_logs(procs);
  const std::size_t coordinator = index_of(processes, "coordinator");
  const std::size_t recorder = index_of(processes, "recorder");
  // Frames the recorder had completed when it was interrupted: the final frame is at least the
  // last of them (the run cannot have gone further than the interrupted member allowed).
  const std::size_t lines_before = count_lines(read_file(out / "vehicles.csv"));
  procs[recorder]->signal(SIGINT);
  // The coordinator's signal comes once the recorder has noticed its own (or has ended).
  ASSERT_TRUE(wait_until(
      [&] {
        return procs[recorder]->log().find("interrupted") != std::string::npos ||
               procs[recorder]->poll().has_value();
      },
      10))
      << describe_logs(procs);
  procs[coordinator]->signal(SIGINT);
  const auto codes = wait_all(procs, 30.0);
  EXPECT_EQ(codes[coordinator], 130) << describe_logs(procs);
  EXPECT_EQ(codes[recorder], 130) << describe_logs(procs);
  for (std::size_t i = 0; i < codes.size(); ++i) {
    if (i != coordinator && i != recorder) {
      EXPECT_EQ(codes[i], 2) << processes[i].member << "\n" << describe_logs(procs);
    }
  }
  const auto summary = nlohmann::json::parse(read_file(out / "summary.json"));
  EXPECT_EQ(summary["status"], "aborted");
  EXPECT_EQ(summary["reason"], "interrupted (signal to the coordinator)");
  const long final_frame = summary["final_frame"];
  EXPECT_GE(1u + 3u * static_cast<std::size_t>(final_frame + 1), lines_before);
  EXPECT_EQ(summary["recorded_up_to_frame"], final_frame);
  // Every vehicle is recorded for every frame up to the final one.
  EXPECT_EQ(count_lines(read_file(out / "vehicles.csv")),
            1u + 3u * static_cast<std::size_t>(final_frame + 1));
}

// A late sensor started with a stale scenario is refused by name; the run goes on and
// completes (before, it aborted the run under way).
TEST(LateJoiner, StaleLateSensorIsRefusedAndTheRunGoesOn) {
  TestRun run;
  const fs::path out = run.dir / "out";
  auto processes = plan(run, kLateCamera, out.string(), "--duration 4 --realtime");
  const auto stale = plan(run, kLateCamera, out.string(), "--duration 3 --realtime");
  const Planned sensor = stale[index_of(stale, "sensor/a")];
  processes.erase(processes.begin() + static_cast<long>(index_of(processes, "sensor/a")));
  auto procs = start_all(run, processes);
  ASSERT_TRUE(wait_until([&] { return count_lines(read_file(out / "vehicles.csv")) > 100; }, 30))
      << describe_logs(procs);
  Process late(sensor.command, run.dir / "sensor_a.log");
  const auto late_code = late.wait(30);
  ASSERT_TRUE(late_code.has_value()) << late.log();
  EXPECT_EQ(*late_code, 3) << late.log();
  EXPECT_NE(late.log().find("scenario mismatch"), std::string::npos) << late.log();
  const auto codes = wait_all(procs, 60.0);
  for (std::size_t i = 0; i < codes.size(); ++i) {
    EXPECT_EQ(codes[i], 0) << processes[i].member << "\n" << describe_logs(procs);
  }
  const std::string log = read_file(run.dir / log_name("coordinator"));
  EXPECT_NE(log.find("refusing member sensor/a: on "), std::string::npos) << log;
  EXPECT_NE(log.find("loaded a different scenario"), std::string::npos) << log;
  const auto summary = nlohmann::json::parse(read_file(out / "summary.json"));
  EXPECT_EQ(summary["status"], "completed");
  EXPECT_EQ(summary["final_frame"], 400);
}

namespace {

// Reads the states and fails when the run has ended (e.g. it cannot write its files).
struct FailingFinisher : TestAgent {
  std::atomic<int> final_states{-1};
  FailingFinisher()
      : TestAgent("recorder", proto::MemberKind::recorder, {{proto::Topic::vehicle_state, ""}}) {}
  void finish(const proto::RunEnd&, const proto::FrameSamples& in) override {
    final_states = static_cast<int>(in.vehicle_states.size());
    throw std::runtime_error("disk full");
  }
};

}  // namespace

// A member that fails after the run completed: the run stays completed (coordinator exit 0),
// the member's own exit status is 3, and the coordinator names it as a failure after the end,
// not as a lost member. Before, the exception left the member's runtime unreported.
TEST(RunEnd, FailureAfterCompletionIsTheMembersOwnNotALoss) {
  TestRun run;
  sdds::DdsOptions dds;
  dds.domain_id = run.domain;
  dds.run_id = run.run_id;
  dds.profiles_file = kConfig + "/dds/profiles.xml";

  sdds::CoordinatorOptions co;
  co.dds = dds;
  co.config_fingerprint = 1;
  co.barrier.members = {"vehicle/x", "recorder"};
  co.barrier.final_frame = 20;
  co.barrier.join_timeout_s = 30;
  co.finish_timeout_s = 20;
  sdds::CoordinatorService coordinator(co);

  StateWriter writer;
  FailingFinisher finisher;
  std::atomic<bool> stop{false};
  std::map<std::string, int> codes;
  std::mutex codes_mutex;
  std::vector<std::thread> threads;
  for (proto::Agent* agent : std::vector<proto::Agent*>{&writer, &finisher}) {
    threads.emplace_back([&, agent] {
      sdds::MemberRuntimeOptions mo;
      mo.dds = dds;
      mo.config_fingerprint = 1;
      sdds::MemberRuntime runtime(*agent, mo);
      int code = -1;
      try {
        code = runtime.run(stop);
      } catch (const std::exception& e) {
        ADD_FAILURE() << agent->member_id() << ": run() threw: " << e.what();
      }
      std::lock_guard lock(codes_mutex);
      codes[agent->member_id()] = code;
    });
  }
  const int code = coordinator.run(stop);
  for (auto& t : threads) t.join();
  EXPECT_EQ(code, sdds::kExitCompleted);
  EXPECT_EQ(coordinator.result().status, proto::RunStatus::completed);
  EXPECT_EQ(codes["vehicle/x"], sdds::kExitCompleted);
  EXPECT_EQ(codes["recorder"], sdds::kExitFailed);
  EXPECT_EQ(finisher.final_states.load(), 1);  // it got the final frame before failing
  const auto& failed = coordinator.failed_after_end();
  ASSERT_EQ(failed.size(), 1u);
  EXPECT_EQ(failed.at("recorder"), "failed while finishing the run: disk full");
  for (const auto& m : coordinator.result().stats.members) EXPECT_FALSE(m.lost) << m.member_id;
}

// The members that left travel with the grant (on_member_loss: continue).
TEST(RunEnd, GrantCarriesTheDepartedMembersOverTheWire) {
  proto::FrameGrantMsg g;
  g.frame = 12;
  g.sim_time_s = 0.12;
  g.joiners = {"sensor/a"};
  g.departed = {"vehicle/b", "controller/b"};
  const proto::FrameGrantMsg back = sdds::from_dds(sdds::to_dds(g));
  EXPECT_EQ(back.frame, 12);
  EXPECT_EQ(back.joiners, g.joiners);
  EXPECT_EQ(back.departed, g.departed);
}
