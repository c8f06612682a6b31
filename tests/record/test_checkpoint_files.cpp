// Checkpoint files of a run directory (record/checkpoint.hpp, docs/checkpoints.md): which
// checkpoints a run keeps.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "core/state_io.hpp"
#include "record/checkpoint.hpp"
#include "record/run_files.hpp"

using namespace syndds;
using namespace syndds::record;
namespace fs = std::filesystem;

namespace {

fs::path fresh_dir() {
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir =
      fs::path(testing::TempDir()) / ("syndds-checkpoint-files-" + std::string(info->name()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A member with a few numbers of state.
struct Counter : proto::Agent {
  explicit Counter(std::string member) : id(std::move(member)) {}
  std::string id;
  std::int64_t count = 0;
  double level = 0.0;
  const std::string& member_id() const override { return id; }
  proto::MemberKind kind() const override { return proto::MemberKind::controller; }
  std::vector<proto::Subscription> subscriptions() const override { return {}; }
  std::vector<proto::Topic> publications() const override { return {}; }
  void step(const proto::FrameContext&, const proto::FrameSamples&, proto::FrameSamples&) override {
  }
  bool can_checkpoint() const override { return true; }
  void save_state(core::StateWriter& w) override {
    w.begin("counter", 1);
    w.io(count);
    w.io(level);
    w.end();
  }
  void load_state(core::StateReader& r) override {
    r.begin("counter", 1);
    r.io(count);
    r.io(level);
    r.end();
  }
};

constexpr std::uint64_t kFingerprint = 0x1234abcd5678ef00ULL;

// Writes every member's file of `frame` and, if `complete`, declares the checkpoint complete.
void write_checkpoint(const fs::path& run_dir, std::int64_t frame, bool complete = true) {
  CheckpointInfo info;
  info.frame = frame;
  info.sim_time_s = 0.01 * static_cast<double>(frame);
  info.fingerprint = kFingerprint;
  for (const char* id : {"vehicle/a", "controller/a"}) {
    Counter agent(id);
    agent.count = frame;
    info.members.push_back({id, write_member_checkpoint(run_dir, frame, kFingerprint, agent, {})});
  }
  if (complete) mark_checkpoint_complete(run_dir, info);
}

std::vector<std::int64_t> frames_on_disk(const fs::path& run_dir) {
  std::vector<std::int64_t> out;
  for (const auto& e : fs::directory_iterator(run_dir / "checkpoints")) {
    out.push_back(std::stoll(e.path().filename().string().substr(6)));
  }
  std::sort(out.begin(), out.end());
  return out;
}

using Frames = std::vector<std::int64_t>;

}  // namespace

// The newest `keep_last` complete checkpoints stay; older complete ones and every incomplete
// one before the newest complete one go.
TEST(CheckpointFiles, PruningKeepsTheNewestCompleteOnes) {
  const fs::path run = fresh_dir();
  for (std::int64_t f : {100, 200, 300, 400}) write_checkpoint(run, f);
  write_checkpoint(run, 450, false);  // a member never wrote its state (e.g. a late joiner)
  write_checkpoint(run, 500);
  EXPECT_EQ(prune_checkpoints(run, 500, 3), (Frames{100, 200, 450}));
  EXPECT_EQ(frames_on_disk(run), (Frames{300, 400, 500}));
  EXPECT_EQ(complete_checkpoints(run), (Frames{300, 400, 500}));
  // What is kept can still be resumed from.
  Counter a("vehicle/a");
  read_member_checkpoint(run, 300, kFingerprint, a);
  EXPECT_EQ(a.count, 300);
  EXPECT_EQ(read_checkpoint_info(run, 300).members.size(), 2u);
  // Nothing more to delete.
  EXPECT_TRUE(prune_checkpoints(run, 500, 3).empty());
  // keep_last 1: only the checkpoint just completed.
  EXPECT_EQ(prune_checkpoints(run, 500, 1), (Frames{300, 400}));
  EXPECT_EQ(frames_on_disk(run), (Frames{500}));
  EXPECT_THROW(prune_checkpoints(run, 500, 0), std::invalid_argument);
}

// Checkpoints after the one just completed are never touched: after a rollback or a resume
// from an older checkpoint they are those of the run's earlier course (rewritten when the run
// gets there), and a member may be writing the next one.
TEST(CheckpointFiles, PruningNeverTouchesNewerCheckpoints) {
  const fs::path run = fresh_dir();
  for (std::int64_t f : {100, 200, 300, 400}) write_checkpoint(run, f);
  write_checkpoint(run, 500, false);  // being written (or left by the course rolled back)
  // A file a member is writing right now (write_file_atomically's temporary file).
  std::ofstream(checkpoint_dir(run, 500) / "sensor.a.state.tmp") << "partial";
  // The run was resumed from 100 and has completed 200 again.
  EXPECT_EQ(prune_checkpoints(run, 200, 1), (Frames{100}));
  EXPECT_EQ(frames_on_disk(run), (Frames{200, 300, 400, 500}));
  EXPECT_TRUE(fs::exists(checkpoint_dir(run, 500) / "sensor.a.state.tmp"));
  EXPECT_EQ(latest_complete_checkpoint(run), std::optional<std::int64_t>(400));
}

// Other entries of the checkpoints folder are not checkpoints and stay.
TEST(CheckpointFiles, PruningLeavesOtherFilesAlone) {
  const fs::path run = fresh_dir();
  write_checkpoint(run, 100);
  write_checkpoint(run, 200);
  fs::create_directories(run / "checkpoints" / "frame_notes");
  std::ofstream(run / "checkpoints" / "frame_000000050") << "a file, not a checkpoint";
  EXPECT_EQ(prune_checkpoints(run, 200, 1), (Frames{100}));
  EXPECT_TRUE(fs::exists(run / "checkpoints" / "frame_notes"));
  EXPECT_TRUE(fs::exists(run / "checkpoints" / "frame_000000050"));
}
