#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include "agents/agent_factory.hpp"
#include "agents/vehicle_agent.hpp"
#include "core/error.hpp"
#include "protocol/local_runner.hpp"
#include "test_agents.hpp"

using namespace syndds;
using syndds::test::StateWriter;
using syndds::test::TestAgent;
namespace fs = std::filesystem;

namespace {

std::string read_file(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string run_default(const std::string& out_dir, double duration) {
  scenario::Overrides o;
  o.duration_s = duration;
  const auto s = scenario::load_scenario(std::string(SYNDDS_TEST_CONFIG_DIR) +
                                         "/scenarios/default.yaml", o);
  record::RecorderOptions ro{out_dir, "test", "single-process"};
  proto::LocalRunner runner(agents::make_all_agents(s, ro),
                            {s.time.final_frame(), s.time.heartbeat_s, false});
  const auto end = runner.run();
  EXPECT_EQ(end.status, proto::RunStatus::completed);
  return read_file(fs::path(out_dir) / "vehicles.csv");
}

}  // namespace

TEST(LocalRunner, RunsTheDefaultScenarioDeterministically) {
  const fs::path base = fs::path(testing::TempDir()) / "local_runner";
  fs::remove_all(base);
  const std::string a = run_default((base / "a").string(), 3.0);
  const std::string b = run_default((base / "b").string(), 3.0);
  EXPECT_EQ(a, b);
  // One header + (frames 0..300) x 3 vehicles.
  EXPECT_EQ(std::count(a.begin(), a.end(), '\n'), 1 + 301 * 3);
  const std::string summary = read_file(base / "a" / "summary.json");
  EXPECT_NE(summary.find("\"status\": \"completed\""), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"frames\": 301"), std::string::npos) << summary;
}

// Frame k sees only samples stamped k-1: a probe agent checks every input it receives.
TEST(LocalRunner, AgentsSeeOnlyThePreviousFrame) {
  struct Probe : TestAgent {
    std::int64_t seen = 0;
    Probe()
        : TestAgent("probe", proto::MemberKind::recorder,
                    {{proto::Topic::vehicle_state, ""}, {proto::Topic::driver_command, ""}}) {}
    void step(const proto::FrameContext& ctx, const proto::FrameSamples& in,
              proto::FrameSamples&) override {
      for (const auto& s : in.vehicle_states) {
        EXPECT_EQ(s.frame, ctx.frame - 1);
        ++seen;
      }
      for (const auto& c : in.driver_commands) EXPECT_EQ(c.frame, ctx.frame - 1);
    }
  };
  const auto s = scenario::load_scenario(std::string(SYNDDS_TEST_CONFIG_DIR) +
                                         "/scenarios/default.yaml");
  std::vector<proto::AgentPtr> agents;
  for (const auto& v : s.vehicles) {
    agents.push_back(agents::make_agent(s, scenario::vehicle_member(v.id), {}));
    agents.push_back(agents::make_agent(s, scenario::controller_member(v.id), {}));
  }
  auto probe = std::make_unique<Probe>();
  Probe* p = probe.get();
  agents.push_back(std::move(probe));
  proto::LocalRunner runner(std::move(agents), {50, 0.01, false});
  runner.run();
  EXPECT_EQ(p->seen, 50 * 3);
}

TEST(LocalRunner, RejectsOutputsWithTheWrongStamp) {
  struct Liar : TestAgent {
    Liar()
        : TestAgent("liar", proto::MemberKind::controller, {}, {proto::Topic::driver_command},
                    "x") {}
    void step(const proto::FrameContext& ctx, const proto::FrameSamples&,
              proto::FrameSamples& out) override {
      proto::DriverCommandMsg c;
      c.vehicle_id = "x";
      c.source = id;
      c.frame = ctx.frame + 1;
      out.driver_commands.push_back(c);
    }
  };
  std::vector<proto::AgentPtr> agents;
  agents.push_back(std::make_unique<Liar>());
  proto::LocalRunner runner(std::move(agents), {3, 0.01, false});
  EXPECT_THROW(runner.run(), ProtocolError);
}

// The DDS writers keep max_per_frame samples per vehicle and frame; one process refuses more
// in the same way, so a run cannot pass in one process and lose samples distributed.
TEST(LocalRunner, RejectsMoreSamplesPerFrameThanTheTopicCarries) {
  struct Chatty : TestAgent {
    Chatty()
        : TestAgent("chatty", proto::MemberKind::controller, {}, {proto::Topic::driver_command},
                    "x") {}
    void step(const proto::FrameContext& ctx, const proto::FrameSamples&,
              proto::FrameSamples& out) override {
      for (std::uint32_t i = 0;
           i <= proto::TopicTraits<proto::Topic::driver_command>::max_per_frame; ++i) {
        out.driver_commands.push_back({"x", id, ctx.frame, 0.0, 0.0, 0.0});
      }
    }
  };
  std::vector<proto::AgentPtr> agents;
  agents.push_back(std::make_unique<Chatty>());
  proto::LocalRunner runner(std::move(agents), {3, 0.01, false});
  try {
    runner.run();
    FAIL() << "no error";
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("driver_command samples in frame 0; at most"),
              std::string::npos)
        << e.what();
  }
}

TEST(VehicleAgent, RejectsNaNAndOutOfRangeCommands) {
  proto::DriverCommandMsg c;
  c.steering = std::nan("");
  EXPECT_EQ(agents::validate_command(c), "steering is not a finite number");
  c.steering = 0.0;
  c.throttle = 1.5;
  EXPECT_NE(agents::validate_command(c).find("throttle = 1.5"), std::string::npos);
  c.throttle = 0.5;
  EXPECT_EQ(agents::validate_command(c), "");

  const auto s = scenario::load_scenario(std::string(SYNDDS_TEST_CONFIG_DIR) +
                                         "/scenarios/default.yaml");
  agents::VehicleAgent vehicle(s, s.vehicles[0]);
  proto::FrameSamples in, out;
  proto::DriverCommandMsg bad;
  bad.vehicle_id = s.vehicles[0].id;
  bad.source = "external/x";
  bad.throttle = std::numeric_limits<double>::quiet_NaN();
  in.driver_commands.push_back(bad);
  vehicle.step({1, 0.01, 0.01, {}, {}, {}}, in, out);
  EXPECT_EQ(vehicle.rejected_commands(), 1u);
  ASSERT_EQ(out.vehicle_states.size(), 1u);
  EXPECT_DOUBLE_EQ(out.vehicle_states[0].throttle, 0.0);  // the bad command was not applied
}

namespace {

// Fails in frame `fail_at`.
struct Failer : TestAgent {
  std::int64_t fail_at = 3;
  Failer() : TestAgent("controller/x", proto::MemberKind::controller) {}
  void step(const proto::FrameContext& ctx, const proto::FrameSamples&,
            proto::FrameSamples&) override {
    if (ctx.frame == fail_at) throw std::runtime_error("boom");
  }
};

// Records the frames of the states it consumed, in steps and at the end.
struct Keeper : TestAgent {
  std::vector<std::int64_t> stepped_frames;  // stamps of the states seen in steps
  std::vector<std::int64_t> final_frames;    // stamps of the final inputs
  std::optional<proto::RunControlMsg> end;
  explicit Keeper(std::string name)
      : TestAgent(std::move(name), proto::MemberKind::recorder,
                  {{proto::Topic::vehicle_state, ""}}) {}
  void step(const proto::FrameContext&, const proto::FrameSamples& in,
            proto::FrameSamples&) override {
    for (const auto& s : in.vehicle_states) stepped_frames.push_back(s.frame);
  }
  void finish(const proto::RunEnd& e, const proto::FrameSamples& in) override {
    end = e.control;
    for (const auto& s : in.vehicle_states) final_frames.push_back(s.frame);
  }
};

}  // namespace

// An agent that throws in frame k: the last complete frame is k-1, and every agent ends up
// having seen its samples exactly once (in a step of frame k or in finish()), as in the
// distributed run. Before, finish() got no inputs and a recorder after the failing agent lost
// frame k-1.
TEST(LocalRunner, AFailureKeepsTheLastCompleteFrame) {
  std::vector<proto::AgentPtr> agents;
  auto before = std::make_unique<Keeper>("before");
  auto after = std::make_unique<Keeper>("recorder");
  Keeper* b = before.get();
  Keeper* a = after.get();
  agents.push_back(std::make_unique<StateWriter>());
  agents.push_back(std::move(before));
  agents.push_back(std::make_unique<Failer>());
  agents.push_back(std::move(after));
  proto::LocalRunner runner(std::move(agents), {10, 0.01, false});
  EXPECT_THROW(runner.run(), std::runtime_error);
  for (Keeper* k : {a, b}) {
    ASSERT_TRUE(k->end.has_value()) << k->id;
    EXPECT_EQ(k->end->status, proto::RunStatus::aborted);
    EXPECT_EQ(k->end->final_frame, 2) << k->id;
    EXPECT_NE(k->end->reason.find("controller/x failed in frame 3: boom"), std::string::npos);
    std::vector<std::int64_t> seen = k->stepped_frames;
    seen.insert(seen.end(), k->final_frames.begin(), k->final_frames.end());
    EXPECT_EQ(seen, (std::vector<std::int64_t>{0, 1, 2})) << k->id;
  }
  EXPECT_EQ(a->final_frames, std::vector<std::int64_t>{2});
  EXPECT_TRUE(b->final_frames.empty());
}
