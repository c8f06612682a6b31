// Checkpoint files of a run directory (record/checkpoint.hpp, docs/checkpoints.md): which
// checkpoints a run keeps, how the files are published, and how damaged ones are refused.
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

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

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
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

// ---- durability ----

namespace {

// Every rename and every fsync of a directory this process makes, in order ("rename TO",
// "fsync DIR"): this program's own definitions stand in for the C library's (found with
// dlsym(RTLD_NEXT)), so the order of the calls the writer makes can be checked.
std::vector<std::string>& file_calls() {
  static std::vector<std::string> calls;
  return calls;
}

std::string fd_path(int fd) {
  std::error_code ec;
  return fs::read_symlink("/proc/self/fd/" + std::to_string(fd), ec).string();
}

}  // namespace

extern "C" int fsync(int fd) {
  using Fn = int (*)(int);
  static const auto real = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "fsync"));
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISDIR(st.st_mode)) file_calls().push_back("fsync " + fd_path(fd));
  return real(fd);
}

extern "C" int rename(const char* from, const char* to) noexcept {
  using Fn = int (*)(const char*, const char*);
  static const auto real = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "rename"));
  const int rc = real(from, to);
  if (rc == 0) file_calls().push_back("rename " + fs::canonical(to).string());
  return rc;
}

// A member's file and complete.yaml are each followed by a sync of their directory, and a
// checkpoint directory created for them by a sync of its parent: after a power loss the
// renames that published them are not lost.
TEST(CheckpointFiles, EveryPublishedFileIsFollowedByASyncOfItsDirectory) {
  const fs::path run = fs::canonical(fresh_dir());
  file_calls().clear();
  write_checkpoint(run, 100);
  const std::string dir = checkpoint_dir(run, 100).string();
  const std::vector<std::string> want = {
      "fsync " + run.string(),                    // checkpoints/ created in RUN_DIR
      "fsync " + (run / "checkpoints").string(),  // frame_000000100 created
      "rename " + dir + "/vehicle.a.state",
      "fsync " + dir,
      "rename " + dir + "/controller.a.state",
      "fsync " + dir,
      "rename " + dir + "/complete.yaml",
      "fsync " + dir};
  EXPECT_EQ(file_calls(), want);
  // The files are whole and read back.
  Counter c("controller/a");
  read_member_checkpoint(run, 100, kFingerprint, c);
  EXPECT_EQ(c.count, 100);
  EXPECT_EQ(read_checkpoint_info(run, 100).members.size(), 2u);
  EXPECT_FALSE(fs::exists(dir + "/complete.yaml.tmp"));
  // The next checkpoint's directory needs only its own entry synced.
  file_calls().clear();
  write_checkpoint(run, 200);
  ASSERT_FALSE(file_calls().empty());
  EXPECT_EQ(file_calls().front(), "fsync " + (run / "checkpoints").string());
}

TEST(CheckpointFiles, ADirectoryThatCannotBeSyncedIsNamed) {
  try {
    sync_directory("/nonexistent-syndds-dir");
    FAIL();
  } catch (const WriteError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-syndds-dir: cannot open the directory"),
              std::string::npos)
        << e.what();
  }
}

// ---- damaged files ----

namespace {

// The error read_checkpoint_info gives for `text` as complete.yaml of frame 300.
std::string complete_yaml_error(const std::string& text) {
  const fs::path run = fresh_dir();
  fs::create_directories(checkpoint_dir(run, 300));
  std::ofstream(checkpoint_dir(run, 300) / "complete.yaml", std::ios::binary) << text;
  try {
    read_checkpoint_info(run, 300);
  } catch (const core::StateError& e) {
    return e.what();
  }
  return "";
}

std::string written_complete_yaml() {
  const fs::path run = fresh_dir();
  write_checkpoint(run, 300);
  return read_file(checkpoint_dir(run, 300) / "complete.yaml");
}

}  // namespace

TEST(CheckpointFiles, AMalformedDeclarationNamesTheFileAndWhatIsWrong) {
  const std::string good = written_complete_yaml();
  ASSERT_EQ(complete_yaml_error(good), "");
  const auto expect_error = [](const std::string& text, const std::string& what) {
    const std::string err = complete_yaml_error(text);
    EXPECT_NE(err.find("frame_000000300/complete.yaml:"), std::string::npos) << err;
    EXPECT_NE(err.find(what), std::string::npos) << "wanted '" << what << "' in: " << err;
  };
  // Truncated: empty, inside a line, at a line end (still valid YAML, members lost).
  expect_error("", "expected a mapping");
  expect_error(good.substr(0, good.find("fingerprint") + 16), "missing required key 'members'");
  const std::string first_member = good.substr(0, good.find("\n", good.find("- {")) + 1);
  expect_error(first_member, "1 members listed, member_count says 2");
  expect_error(good.substr(0, good.find("member_count")), "missing required key 'members'");
  // Wrong types.
  std::string bad = good;
  bad.replace(bad.find("frame: 300"), 10, "frame: [300]");
  expect_error(bad, "frame: expected an integer");
  bad = good;
  bad.replace(bad.find("sim_time_s: 3"), 13, "sim_time_s: soon");
  expect_error(bad, "sim_time_s: expected a number, got 'soon'");
  bad = good;
  bad.replace(bad.find("0x"), 2, "0y");
  expect_error(bad, "fingerprint: expected 0x and up to 16 hexadecimal digits");
  bad = good;
  bad.replace(bad.find("bytes: "), 7, "bytes: -");
  expect_error(bad, "members[0].bytes: expected a positive number of bytes");
  bad = good;
  bad.replace(bad.find("members:"), 8, "members: 2\nx:");
  expect_error(bad, "members: expected a list");
  // Missing and unknown keys; a declaration of another frame.
  bad = good;
  bad.replace(bad.find("sim_time_s"), 10, "sim_time");
  expect_error(bad, "missing required key 'sim_time_s'");
  bad = good;
  bad.replace(bad.find("id: "), 4, "name: ");
  expect_error(bad, "missing required key 'id'");
  bad = good;
  bad.replace(bad.find("frame: 300"), 10, "frame: 200");
  expect_error(bad, "frame: says frame 200, but the checkpoint is of frame 300");
  expect_error(good + "extra: 1\n", "unknown key 'extra'");
  expect_error("frame: 300\n  bad: [\n", "YAML syntax error");
}

TEST(CheckpointFiles, AMissingCheckpointNamesTheOnesThereAre) {
  const fs::path run = fresh_dir();
  write_checkpoint(run, 300);
  write_checkpoint(run, 400);
  write_checkpoint(run, 500, false);
  try {
    read_checkpoint_info(run, 200);
    FAIL();
  } catch (const core::StateError& e) {
    EXPECT_NE(std::string(e.what()).find("frame_000000200: no such checkpoint (complete "
                                         "checkpoints: 300, 400; checkpoint.keep_last"),
              std::string::npos)
        << e.what();
  }
  try {
    read_checkpoint_info(run, 500);
    FAIL();
  } catch (const core::StateError& e) {
    EXPECT_NE(std::string(e.what()).find("frame_000000500: not a complete checkpoint"),
              std::string::npos)
        << e.what();
  }
}

// A member's state file whose header or member section is wrong is refused with its name.
TEST(CheckpointFiles, AMalformedMemberFileNamesTheFileAndWhatIsWrong) {
  const fs::path run = fresh_dir();
  write_checkpoint(run, 300);
  const fs::path file = checkpoint_dir(run, 300) / "vehicle.a.state";
  const std::string good = read_file(file);
  const auto error_for = [&](const std::string& bytes, const std::string& member = "vehicle/a",
                             std::int64_t frame = 300,
                             std::uint64_t fingerprint = kFingerprint) -> std::string {
    std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
    Counter agent(member);
    try {
      read_member_checkpoint(run, frame, fingerprint, agent);
    } catch (const core::StateError& e) {
      return e.what();
    }
    return "";
  };
  const auto expect_error = [&](const std::string& err, const std::string& what) {
    EXPECT_NE(err.find("vehicle.a.state"), std::string::npos) << err;
    EXPECT_NE(err.find(what), std::string::npos) << "wanted '" << what << "' in: " << err;
  };
  ASSERT_EQ(error_for(good), "");
  const std::size_t header_end = good.find('\n', good.find('\n') + 1) + 1;
  expect_error(error_for(""), "not a syndds state file");
  expect_error(error_for(good.substr(0, 20)), "the header line is cut off");
  expect_error(error_for(good.substr(0, header_end + 10)), "the file is truncated");
  std::string bad = good;
  bad.replace(good.find('\n') + 1, 0, "-");
  expect_error(error_for(bad), "malformed header '-");
  bad = good;
  bad.replace(header_end - 5, 4, "XYZW");
  expect_error(error_for(bad), "16-digit hexadecimal checksum");
  bad = good;
  bad[header_end + 20] ^= 0x01;
  expect_error(error_for(bad), "checksum");
  // Whole files, but not this member's, frame's or scenario's.
  fs::copy_file(checkpoint_dir(run, 300) / "controller.a.state", file,
                fs::copy_options::overwrite_existing);
  expect_error(error_for(read_file(file)),
               "the state of member 'controller/a', not of 'vehicle/a'");
  expect_error(error_for(good, "vehicle/a", 300, kFingerprint + 1),
               "a resumed run needs the same scenario files and overrides");
  const fs::path missing = checkpoint_dir(run, 300) / "sensor.a.state";
  Counter sensor("sensor/a");
  try {
    read_member_checkpoint(run, 300, kFingerprint, sensor);
    FAIL();
  } catch (const core::StateError& e) {
    EXPECT_NE(std::string(e.what()).find(missing.string() + ": cannot be read"), std::string::npos)
        << e.what();
  }
}

// A checkpoint records the build that wrote it; another build (other physics or protocol
// sources) refuses to resume from it, naming both builds.
TEST(CheckpointFiles, ACheckpointOfAnotherBuildIsRefusedNamingBothBuilds) {
  const fs::path run = fresh_dir();
  Counter writer("vehicle/a");
  writer.count = 7;
  write_member_checkpoint(run, 100, kFingerprint, writer, {}, "0.0.1+00000000deadbeef");
  Counter reader("vehicle/a");
  try {
    read_member_checkpoint(run, 100, kFingerprint, reader);
    FAIL() << "a checkpoint of another build was resumed";
  } catch (const core::StateError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("vehicle.a.state"), std::string::npos) << what;
    EXPECT_NE(what.find("written by syndds build 0.0.1+00000000deadbeef; this program is build " +
                        std::string(build_identity())),
              std::string::npos)
        << what;
  }
  write_member_checkpoint(run, 100, kFingerprint, writer, {});  // this build's: fine
  read_member_checkpoint(run, 100, kFingerprint, reader);
  EXPECT_EQ(reader.count, 7);
}
