#include "record/checkpoint.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/state_io.hpp"
#include "core/yaml.hpp"
#include "protocol/sample_state.hpp"
#include "record/run_files.hpp"

namespace syndds::record {
namespace fs = std::filesystem;
namespace {

constexpr const char* kComplete = "complete.yaml";

std::string read_all(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw core::StateError(path.string() + ": cannot be read (no checkpoint state there)");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The checkpoint directories of `run_dir` (frame_<digits>), oldest first.
std::vector<std::pair<std::int64_t, fs::path>> checkpoint_dirs(const fs::path& run_dir) {
  std::vector<std::pair<std::int64_t, fs::path>> out;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(run_dir / "checkpoints", ec)) {
    const std::string name = entry.path().filename().string();
    constexpr std::string_view kPrefix = "frame_";
    if (!name.starts_with(kPrefix) || name.size() == kPrefix.size()) continue;
    std::int64_t frame = -1;
    const char* first = name.data() + kPrefix.size();
    const char* last = name.data() + name.size();
    const auto [end, error] = std::from_chars(first, last, frame);
    if (error != std::errc() || end != last || frame < 0 || !entry.is_directory(ec)) continue;
    out.emplace_back(frame, entry.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

fs::path checkpoint_dir(const fs::path& run_dir, std::int64_t frame) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%09lld", static_cast<long long>(frame));
  return run_dir / "checkpoints" / name;
}

std::string member_state_file(const std::string& member_id) {
  std::string name = member_id;
  for (char& c : name) {
    if (c == '/') c = '.';
  }
  return name + ".state";
}

std::uint64_t write_member_checkpoint(const fs::path& run_dir, std::int64_t frame,
                                      std::uint64_t fingerprint, proto::Agent& agent,
                                      const proto::FrameSamples& next_inputs,
                                      const std::string& build_id) {
  core::StateWriter w;
  w.begin("member", 2);
  w.io(agent.member_id());
  w.io(frame);
  w.io(fingerprint);
  w.io(build_id);
  agent.save_state(w);
  proto::save_samples(w, next_inputs);
  w.end();
  const fs::path dir = checkpoint_dir(run_dir, frame);
  create_directories_durably(dir);
  const std::string framed = core::frame_state(w.bytes());
  write_file_atomically(dir / member_state_file(agent.member_id()), framed);
  return framed.size();
}

proto::FrameSamples read_member_checkpoint(const fs::path& run_dir, std::int64_t frame,
                                           std::uint64_t fingerprint, proto::Agent& agent) {
  const fs::path file = checkpoint_dir(run_dir, frame) / member_state_file(agent.member_id());
  const std::string bytes = core::unframe_state(read_all(file), file.string());
  core::StateReader r(bytes, file.string());
  r.begin("member", 2);
  const auto member = r.get<std::string>();
  if (member != agent.member_id()) {
    r.fail("the state of member '" + member + "', not of '" + agent.member_id() + "'");
  }
  const auto saved_frame = r.get<std::int64_t>();
  if (saved_frame != frame) {
    r.fail("the state of frame " + std::to_string(saved_frame) + ", not of frame " +
           std::to_string(frame));
  }
  const auto saved_fingerprint = r.get<std::uint64_t>();
  if (saved_fingerprint != fingerprint) {
    r.fail("written for scenario fingerprint 0x" + hex64(saved_fingerprint) + "; this run's is 0x" +
           hex64(fingerprint) + " (a resumed run needs the same scenario files and overrides)");
  }
  const auto saved_build = r.get<std::string>();
  if (saved_build != build_identity()) {
    r.fail("written by syndds build " + saved_build + "; this program is build " +
           build_identity() + " (other physics or protocol sources: resume with the build that "
           "wrote it)");
  }
  agent.load_state(r);
  proto::FrameSamples inputs = proto::load_samples(r);
  r.end();
  if (!r.at_end()) r.fail("bytes after the member's state");
  return inputs;
}

void mark_checkpoint_complete(const fs::path& run_dir, const CheckpointInfo& info) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "frame" << YAML::Value << info.frame;
  out << YAML::Key << "sim_time_s" << YAML::Value << info.sim_time_s;
  out << YAML::Key << "fingerprint" << YAML::Value << "0x" + hex64(info.fingerprint);
  out << YAML::Key << "member_count" << YAML::Value << info.members.size();
  out << YAML::Key << "members" << YAML::Value << YAML::BeginSeq;
  for (const auto& m : info.members) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "id" << YAML::Value << m.member_id
        << YAML::Key << "bytes" << YAML::Value << m.bytes << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  write_file_atomically(checkpoint_dir(run_dir, info.frame) / kComplete,
                        std::string(out.c_str()) + "\n");
}

CheckpointInfo read_checkpoint_info(const fs::path& run_dir, std::int64_t frame) {
  const fs::path dir = checkpoint_dir(run_dir, frame);
  const fs::path file = dir / kComplete;
  if (!fs::exists(file)) {
    if (!fs::exists(dir)) {
      std::string kept;
      for (const auto f : complete_checkpoints(run_dir)) {
        kept += (kept.empty() ? "" : ", ") + std::to_string(f);
      }
      throw core::StateError(dir.string() + ": no such checkpoint (complete checkpoints: " +
                             (kept.empty() ? std::string("none") : kept) +
                             "; checkpoint.keep_last says how many a run keeps)");
    }
    throw core::StateError(dir.string() + ": not a complete checkpoint (no " + kComplete +
                           "; some member never wrote its state)");
  }
  // Every error names the file, the line and the key (YamlNode); a damaged file may still be
  // valid YAML, so every key is required and the member list is checked against its count.
  try {
    const YamlNode root = YamlNode::load_file(file.string());
    MapReader m(root);
    CheckpointInfo info;
    const YamlNode frame_node = m.required("frame");
    info.frame = frame_node.as_int();
    if (info.frame != frame) {
      frame_node.fail("says frame " + std::to_string(info.frame) + ", but the checkpoint is of " +
                      "frame " + std::to_string(frame));
    }
    info.sim_time_s = m.get<double>("sim_time_s");
    const YamlNode fingerprint = m.required("fingerprint");
    const std::string text = fingerprint.as_string();
    std::uint64_t value = 0;
    const char* first = text.data() + std::min<std::size_t>(2, text.size());
    const char* last = text.data() + text.size();
    const auto [end, error] = std::from_chars(first, last, value, 16);
    if (!text.starts_with("0x") || first == last || error != std::errc() || end != last ||
        text.size() > 18) {
      fingerprint.fail("expected 0x and up to 16 hexadecimal digits, got '" + text + "'");
    }
    info.fingerprint = value;
    const std::optional<YamlNode> count = m.optional("member_count");
    const YamlNode members = m.required("members");
    for (const auto& node : members.elements()) {
      MapReader member(node);
      CheckpointMember entry;
      entry.member_id = member.get<std::string>("id");
      if (entry.member_id.empty()) member.required("id").fail("empty member id");
      const YamlNode bytes = member.required("bytes");
      const std::int64_t n = bytes.as_int();
      if (n <= 0) bytes.fail("expected a positive number of bytes, got " + std::to_string(n));
      entry.bytes = static_cast<std::uint64_t>(n);
      member.finish();
      info.members.push_back(std::move(entry));
    }
    if (info.members.empty()) members.fail("no members (expected at least one)");
    if (count && count->as_int() != static_cast<std::int64_t>(info.members.size())) {
      members.fail(std::to_string(info.members.size()) + " members listed, member_count says " +
                   std::to_string(count->as_int()) + " (the file is cut short?)");
    }
    m.finish();
    return info;
  } catch (const ConfigError& e) {
    throw core::StateError(std::string("malformed checkpoint declaration: ") + e.what());
  }
}

std::optional<std::int64_t> latest_complete_checkpoint(const fs::path& run_dir) {
  const auto frames = complete_checkpoints(run_dir);
  if (frames.empty()) return std::nullopt;
  return frames.back();
}

std::vector<std::int64_t> complete_checkpoints(const fs::path& run_dir) {
  std::vector<std::int64_t> out;
  for (const auto& [frame, dir] : checkpoint_dirs(run_dir)) {
    if (fs::exists(dir / kComplete)) out.push_back(frame);
  }
  return out;
}

std::vector<std::int64_t> prune_checkpoints(const fs::path& run_dir, std::int64_t completed,
                                            std::int64_t keep_last) {
  if (keep_last < 1) throw std::invalid_argument("prune_checkpoints: keep_last must be >= 1");
  std::vector<std::pair<std::int64_t, fs::path>> doomed;
  std::int64_t kept = 1;  // `completed`
  const auto dirs = checkpoint_dirs(run_dir);
  for (auto it = dirs.rbegin(); it != dirs.rend(); ++it) {
    const auto& [frame, dir] = *it;
    if (frame >= completed) continue;
    if (fs::exists(dir / kComplete) && kept < keep_last) {
      ++kept;
      continue;
    }
    doomed.emplace_back(frame, dir);
  }
  std::vector<std::int64_t> deleted;
  for (auto it = doomed.rbegin(); it != doomed.rend(); ++it) {
    const auto& [frame, dir] = *it;
    // complete.yaml first: a prune cut short leaves an incomplete checkpoint (deleted by the
    // next prune), never a complete one with files missing.
    std::error_code ec;
    fs::remove(dir / kComplete, ec);
    if (!ec) fs::remove_all(dir, ec);
    if (ec) throw WriteError(dir.string() + ": cannot delete: " + ec.message());
    deleted.push_back(frame);
  }
  return deleted;
}

CheckpointInfo write_local_checkpoint(const fs::path& run_dir, proto::FrameStepper& stepper,
                                      std::uint64_t fingerprint, double heartbeat_s) {
  CheckpointInfo info;
  info.frame = stepper.next_frame() - 1;
  info.sim_time_s = static_cast<double>(info.frame) * heartbeat_s;
  info.fingerprint = fingerprint;
  const auto& agents = stepper.agents();
  for (std::size_t i = 0; i < agents.size(); ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto bytes = write_member_checkpoint(run_dir, info.frame, fingerprint, *agents[i],
                                               stepper.next_inputs(i));
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    info.members.push_back({agents[i]->member_id(), bytes, s});
  }
  mark_checkpoint_complete(run_dir, info);
  return info;
}

void resume_local(const fs::path& run_dir, std::int64_t frame, std::uint64_t fingerprint,
                  proto::FrameStepper& stepper) {
  const CheckpointInfo info = read_checkpoint_info(run_dir, frame);
  const auto& agents = stepper.agents();
  std::vector<proto::FrameSamples> inputs;
  for (const auto& agent : agents) {
    inputs.push_back(read_member_checkpoint(run_dir, frame, fingerprint, *agent));
  }
  stepper.resume(info.frame, std::move(inputs));
}

}  // namespace syndds::record
