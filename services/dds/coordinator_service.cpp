#include "dds/coordinator_service.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include "core/build_identity.hpp"
#include "dds/convert.hpp"
#include "dds/member_runtime.hpp"
#include "record/checkpoint.hpp"
#include "record/run_files.hpp"

namespace syndds::dds {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

CoordinatorService::CoordinatorService(CoordinatorOptions options) : options_(std::move(options)) {}

CoordinatorService::~CoordinatorService() { close(); }

void CoordinatorService::close() {
  // Stop every DDS callback into this object before its members go (see MemberRuntime).
  if (participant_) participant_->remove_lost_callback(lost_callback_);
  watch_.stop();
  announce_reader_.reset();
  done_reader_.reset();
  dones_reader_.reset();
  announce_writer_.reset();
  grant_writer_.reset();
  control_writer_.reset();
  participant_.reset();
}

double CoordinatorService::now() const { return seconds_since(t0_); }

void CoordinatorService::setup() {
  participant_ = std::make_unique<Participant>(options_.dds);
  lost_callback_ = participant_->add_lost_callback(
      [this](const std::string& guid, bool graceful) { on_lost(guid, graceful); });
  // Writers before readers: a reader's callback may decide a grant at once (members that
  // announced themselves before the coordinator started are delivered as soon as it matches).
  grant_writer_ =
      participant_->make_writer<msg::FrameGrant>(topics::kFrameGrant, profiles::kProtocolWriter);
  control_writer_ =
      participant_->make_writer<msg::RunControl>(topics::kRunControl, profiles::kProtocolWriter);
  announce_writer_ = participant_->make_writer<msg::MemberAnnounce>(topics::kMemberAnnounce,
                                                                    profiles::kProtocolWriter);
  // The announcement's fixed part, before a reader's callback may announce it again.
  announcement_ = announcement_of(*participant_, "coordinator", proto::MemberKind::coordinator,
                                  options_.config_fingerprint, options_.config_files,
                                  build_identity());
  proto::MemberAnnounceMsg& a = announcement_;
  a.expected_members = options_.barrier.members;
  a.expected_members.insert(a.expected_members.end(), options_.barrier.late_members.begin(),
                            options_.barrier.late_members.end());
  a.join_timeout_s = options_.barrier.join_timeout_s;
  a.frame_timeout_s = options_.barrier.frame_timeout_s;
  a.checkpoint_every = options_.barrier.checkpoint_every;
  announce_reader_ = participant_->make_reader<msg::MemberAnnounce>(
      topics::kMemberAnnounce, profiles::kProtocolReader,
      [this](msg::MemberAnnounce&& m, const fdds::SampleInfo& info) {
        if (m.kind() == msg::MEMBER_COORDINATOR) return;
        try {
          on_join(from_dds(m), to_string(writer_prefix(info)));
        } catch (const std::exception& e) {
          malformed("member_announce from " + m.member_id(), e.what());
        }
      });
  done_reader_ = participant_->make_reader<msg::FrameDone>(
      topics::kFrameDone, profiles::kProtocolReader,
      [this](msg::FrameDone&& m, const fdds::SampleInfo& info) {
        try {
          count_done_sample();
          on_done(from_dds(m), to_string(writer_prefix(info)));
        } catch (const std::exception& e) {
          malformed("frame_done from " + m.member_id(), e.what());
        }
      });
  // Several members' dones from one process: each counts as if it had come alone.
  dones_reader_ = participant_->make_reader<msg::FrameDones>(
      topics::kFrameDones, profiles::kProtocolReader,
      [this](msg::FrameDones&& m, const fdds::SampleInfo& info) {
        proto::FrameDonesMsg batch;
        try {
          count_done_sample();
          batch = from_dds(m);
        } catch (const std::exception& e) {
          malformed("frame_dones from participant " + to_string(writer_prefix(info)), e.what());
          return;
        }
        const std::string writer = to_string(writer_prefix(info));
        for (const auto& d : batch.dones) on_done(d, writer);
      });
  std::lock_guard lock(mutex_);
  announce_locked();
}

// The announcement with the admission's current lists: written at the start and whenever who is
// which member changed (a claimant waits for its name in `admitted` or `refused`).
void CoordinatorService::announce_locked() {
  announcement_.admitted = admission_.admitted_list();
  announcement_.refused = admission_.refused_list();
  if (!announce_writer_->write(to_dds(announcement_))) {
    barrier_->on_interrupt("DDS refused a member_announce sample", now());
  }
}

// Intrusions are logged when seen and carried to the members (the recorder) by the next grant.
void CoordinatorService::note_intrusions_locked() {
  for (auto& i : admission_.take_intrusions()) {
    spdlog::warn("coordinator: intrusion: participant {} {} as {}", i.participant, i.what,
                 i.member);
    intrusions_.push_back(i.member + " " + i.participant + " " + i.what);
  }
  if (admission_.take_changed()) announce_locked();
}

// A malformed protocol message aborts the run naming it (ignoring it would end in a deadline
// that blames the wrong member).
void CoordinatorService::malformed(const std::string& what, const std::string& error) {
  std::lock_guard lock(mutex_);
  barrier_->on_interrupt("malformed " + what + ": " + error, now());
  advance_locked();
}

std::string CoordinatorService::differing_files(const proto::MemberAnnounceMsg& a) const {
  const std::string d = proto::config_file_differences(options_.config_files, a.config_files);
  return d.empty() ? std::string(proto::kFingerprintHint)
                   : "files that differ (here, on " + a.host + "): " + d;
}

void CoordinatorService::on_join(const proto::MemberAnnounceMsg& a, const std::string& writer) {
  std::lock_guard lock(mutex_);
  if (a.participant_guid != writer) {
    // Only a participant may say who it is: an announcement naming another one is forged.
    admission_.refuse(a.member_id, writer,
                      "its announcement names participant " + a.participant_guid);
    note_intrusions_locked();
    return;
  }
  announced_by_[a.member_id] = a.participant_guid;
  join_locked(a);
  cv_.notify_all();  // reach_members_before_start waits for announcements
}

void CoordinatorService::join_locked(const proto::MemberAnnounceMsg& a) {
  if (!barrier_->is_member(a.member_id)) {
    spdlog::warn("coordinator: refusing {} (pid {} on {}): not a member of this scenario",
                 a.member_id, a.pid, a.host);
    admission_.refuse(a.member_id, a.participant_guid, "not a member of this scenario");
    note_intrusions_locked();
    return;
  }
  std::string mismatch;
  if (a.config_fingerprint != options_.config_fingerprint) {
    mismatch = "on " + a.host + " loaded a different scenario or overrides (fingerprint " +
               proto::fingerprint_hex(a.config_fingerprint) + ", coordinator " +
               proto::fingerprint_hex(options_.config_fingerprint) + "); " +
               differing_files(a);
  } else if (a.protocol_version != proto::kProtocolVersion) {
    mismatch = "speaks protocol version " + std::to_string(a.protocol_version);
  } else if (!a.build_id.empty() && a.build_id != announcement_.build_id) {
    mismatch = "on " + a.host + " runs syndds build " + a.build_id + ", the coordinator build " +
               announcement_.build_id +
               " (other physics or protocol sources: build every host from the same commit)";
  }
  if (!mismatch.empty()) {
    // A member the start waits for aborts the run; a late one is refused and the run goes on.
    const std::string refused = barrier_->on_config_mismatch(a.member_id, mismatch, now());
    if (!refused.empty()) {
      spdlog::error("coordinator: {}", refused);
      admission_.refuse(a.member_id, a.participant_guid, mismatch);
      note_intrusions_locked();
    }
  } else {
    const auto rejoining = barrier_->rejoining_members();
    const bool rejoin =
        std::find(rejoining.begin(), rejoining.end(), a.member_id) != rejoining.end();
    const auto known = guid_of_member_.find(a.member_id);
    const auto claim = admission_.on_claim(a.member_id, a.participant_guid, rejoin, now());
    if (claim == proto::Admission::Claim::held) {
      // Another participant under a name already taken: a restart seen before its old
      // process's exit (taken once the loss is seen), or else refused when the hold ends.
      if (!held_announcements_.contains(a.member_id) ||
          held_announcements_[a.member_id].participant_guid != a.participant_guid) {
        spdlog::warn("coordinator: holding {} announced by participant {} (pid {} on {}): "
                     "participant {} is that member", a.member_id, a.participant_guid, a.pid,
                     a.host, known == guid_of_member_.end() ? "?" : known->second);
      }
      held_announcements_[a.member_id] = a;
      advance_locked();
      return;
    }
    if (claim == proto::Admission::Claim::refused) {
      note_intrusions_locked();
      advance_locked();
      return;
    }
    held_announcements_.erase(a.member_id);
    if (rejoin && known != guid_of_member_.end()) {
      // The member's old participant is gone: its lease running out later is not a new loss.
      auto& old = members_of_guid_[known->second];
      old.erase(std::remove(old.begin(), old.end(), a.member_id), old.end());
      spdlog::info("coordinator: {} announced itself again (pid {} on {})", a.member_id, a.pid,
                   a.host);
    }
    guid_of_member_[a.member_id] = a.participant_guid;
    auto& members = members_of_guid_[a.participant_guid];
    if (std::find(members.begin(), members.end(), a.member_id) == members.end()) {
      members.push_back(a.member_id);
    }
    if (!a.process_key.empty() && process_of_guid_.emplace(a.participant_guid, a.process_key).second) {
      const std::string guid = a.participant_guid;
      watch_.watch(a.process_key, [this, guid] { on_process_exit(guid); });
    }
    const std::string warning = barrier_->on_join(a.member_id, now());
    if (!warning.empty()) spdlog::warn("coordinator: {}", warning);
    note_intrusions_locked();
  }
  advance_locked();
}

void CoordinatorService::on_process_exit(const std::string& guid) {
  if (options_.debug_exit_notice_delay_s > 0.0) {  // on the watch's thread, outside the lock
    std::this_thread::sleep_for(std::chrono::duration<double>(options_.debug_exit_notice_delay_s));
  }
  std::lock_guard lock(mutex_);
  const auto it = members_of_guid_.find(guid);
  if (it == members_of_guid_.end() || !barrier_) return;
  for (const auto& member : it->second) {
    barrier_->on_member_lost(member, "its process exited", now());
  }
  note_recovering_locked();
  replay_held_locked();
  advance_locked();
}

void CoordinatorService::count_done_sample() {
  std::lock_guard lock(mutex_);
  ++done_samples_;
}

void CoordinatorService::on_done(const proto::FrameDoneMsg& d, const std::string& writer) {
  std::lock_guard lock(mutex_);
  if (d.finished) {
    // Heard the verdict, whether or not its announcement has arrived yet (for
    // reach_members_before_start only: it decides nothing about the run).
    verdict_heard_by_.insert(d.member_id);
    cv_.notify_all();
  }
  // A done counts only from the participant admitted as its member: a second copy of a member
  // (or anybody writing in its name) cannot finish, fail or abort anything.
  if (!admission_.accept(d.member_id, writer, "frame_done")) {
    note_intrusions_locked();
    advance_locked();
    return;
  }
  const std::string warning = barrier_->on_done(d, now());
  if (!warning.empty()) spdlog::warn("coordinator: {}", warning);
  advance_locked();
}

void CoordinatorService::on_lost(const std::string& guid, bool graceful) {
  std::lock_guard lock(mutex_);
  std::erase_if(held_announcements_, [&](const auto& h) { return h.second.participant_guid == guid; });
  admission_.forget(guid);
  auto it = members_of_guid_.find(guid);
  if (it == members_of_guid_.end()) return;
  if (!graceful) {
    // The lease expired. A process of this machine is watched directly (its exit is seen at
    // once): while it still runs it is slow (load, SIGSTOP, a debugger), not dead, and its
    // participant is found again when its announcements resume.
    const auto p = process_of_guid_.find(guid);
    if (p != process_of_guid_.end() && watch_.watching(p->second)) {
      std::string names;
      for (const auto& m : it->second) names += (names.empty() ? "" : ", ") + m;
      spdlog::warn("coordinator: the DDS lease of {} expired but its process is running "
                   "(overloaded or stopped?): not lost unless the process exits",
                   names);
      return;
    }
  }
  // Members grouped in one process share its participant: they are lost together.
  for (const auto& member : it->second) {
    barrier_->on_member_lost(member,
                             graceful ? "its DDS participant left (process ended)"
                                      : "liveliness lost (no DDS announcement within the lease)",
                             now());
  }
  note_recovering_locked();
  replay_held_locked();
  advance_locked();
}

// Acts on the barrier's decisions until it says wait. Called with mutex_ held.
void CoordinatorService::declare_checkpoint(const proto::CheckpointReport& report) {
  if (!report.missing.empty()) {
    std::string names;
    for (const auto& m : report.missing) names += (names.empty() ? "" : ", ") + m;
    spdlog::warn("coordinator: the checkpoint of frame {} is incomplete: no state from {}",
                 report.frame, names);
    return;
  }
  record::CheckpointInfo info;
  info.frame = report.frame;
  info.sim_time_s = static_cast<double>(report.frame) * options_.barrier.heartbeat_s;
  info.fingerprint = options_.config_fingerprint;
  std::uint64_t bytes = 0;
  for (const auto& [member, n] : report.members) {
    info.members.push_back({member, n});
    bytes += n;
  }
  try {
    record::mark_checkpoint_complete(options_.run_dir, info);
    spdlog::info("coordinator: checkpoint of frame {} (t = {:g} s) complete: {} members, {} bytes",
                 info.frame, info.sim_time_s, info.members.size(), bytes);
  } catch (const std::exception& e) {
    // The run goes on; the previous complete checkpoint stays the one to resume from.
    spdlog::error("coordinator: checkpoint of frame {}: {}", info.frame, e.what());
    return;
  }
  // Every member's file of this checkpoint and of the older ones was written before its
  // FrameDone was counted, and none is writing a newer one yet (frame info.frame + 2 is granted
  // after this): the older checkpoints can go.
  try {
    const auto deleted =
        record::prune_checkpoints(options_.run_dir, info.frame, options_.checkpoint_keep_last);
    if (!deleted.empty()) {
      spdlog::debug("coordinator: deleted the checkpoints of frames {} to {} (keep_last {})",
                    deleted.front(), deleted.back(), options_.checkpoint_keep_last);
    }
  } catch (const std::exception& e) {
    spdlog::warn("coordinator: old checkpoints: {}", e.what());
  }
}

void CoordinatorService::replay_held_locked() {
  if (held_announcements_.empty()) return;
  for (const auto& member : barrier_->rejoining_members()) {
    const auto held = held_announcements_.find(member);
    if (held == held_announcements_.end()) continue;
    const proto::MemberAnnounceMsg a = held->second;
    held_announcements_.erase(held);
    const auto still = admission_.held(member);
    if (std::find(still.begin(), still.end(), a.participant_guid) == still.end()) continue;
    spdlog::info("coordinator: {} had announced itself again before its loss was seen (pid {} "
                 "on {}): taking that announcement", member, a.pid, a.host);
    join_locked(a);
  }
}

void CoordinatorService::note_recovering_locked() {
  const auto waiting = barrier_->rejoining_members();
  if (waiting.empty()) return;
  std::string names;
  for (const auto& m : waiting) names += (names.empty() ? "" : ", ") + m;
  if (names == recovering_logged_) return;
  recovering_logged_ = names;
  spdlog::warn("coordinator: recovering: waiting up to {:g} s for {} to announce itself again; "
               "then every member rolls back to the checkpoint of frame {}",
               options_.barrier.rejoin_timeout_s, names, barrier_->last_checkpoint());
}

void CoordinatorService::note_recovery_locked(const proto::FrameGrantMsg& grant) {
  recovering_logged_.clear();
  const proto::Recovery& r = barrier_->recoveries().back();
  std::string names;
  for (const auto& [member, why] : r.members) names += (names.empty() ? "" : ", ") + member;
  spdlog::warn("coordinator: recovery {}: {} lost in frame {}; every member rolls back to the "
               "checkpoint of frame {} and goes on", barrier_->recoveries().size(), names,
               r.lost_in, r.to_checkpoint);
  recovery_wall_s_.push_back(
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count());
  if (options_.run_dir.empty()) return;
  // The run's record of its recoveries (the CSV files of the run hold no trace of them: they
  // are byte-identical to an undisturbed run's).
  try {
    const std::filesystem::path file = std::filesystem::path(options_.run_dir) / "recoveries.csv";
    const bool fresh = !std::filesystem::exists(file);
    std::ofstream out(file, std::ios::app);
    if (fresh) out << "recovery,lost_in_frame,rolled_back_to_frame,member,why\n";
    for (const auto& [member, why] : r.members) {
      out << barrier_->recoveries().size() << ',' << r.lost_in << ',' << r.to_checkpoint << ','
          << member << ",\"" << why << "\"\n";
    }
    if (!out) throw std::runtime_error("cannot write " + file.string());
  } catch (const std::exception& e) {
    spdlog::error("coordinator: recoveries.csv: {}", e.what());
  }
}

void CoordinatorService::advance_locked() {
  using Kind = proto::Barrier::Action::Kind;
  while (!end_) {
    auto action = barrier_->poll(now());
    if (auto checkpoint = barrier_->take_checkpoint()) declare_checkpoint(*checkpoint);
    if (action.kind == Kind::grant) {
      if (action.grant.rollback) {
        note_recovery_locked(action.grant);
        for (auto& member : action.grant.rejoined) member += " " + guid_of_member_[member];
      }
      action.grant.intrusions = std::move(intrusions_);
      intrusions_.clear();
      for (const auto& j : action.grant.joiners) {
        spdlog::info("coordinator: {} joins the run at frame {}", j, action.grant.frame + 1);
      }
      granted_frame_ = action.grant.frame;
      if (action.grant.frame == options_.barrier.first_frame) {
        spdlog::info("coordinator: all members joined after {:.2f} s; starting", now());
        write_status_locked("running");
      } else if (action.grant.rollback) {
        write_status_locked("running");
      } else if (action.grant.frame % progress_every_ == 0) {
        spdlog::info("coordinator: frame {}/{}", action.grant.frame, options_.barrier.final_frame);
      }
      if (!grant_writer_->write(to_dds(action.grant))) {
        barrier_->on_interrupt("DDS refused a frame_grant sample", now());
      }
      continue;
    }
    if (action.kind == Kind::wait) {
      next_wake_s_ = action.wake_at_s;
      return;
    }
    end_ = std::move(action);
    cv_.notify_all();
  }
  cv_.notify_all();  // after the end: finished replies wake wait_for_finished
}

void CoordinatorService::wait_for_finished(std::unique_lock<std::mutex>& lock) {
  const double deadline = now() + options_.finish_timeout_s;
  while (!barrier_->all_finished() && now() < deadline) {
    cv_.wait_for(lock, std::chrono::milliseconds(50));
  }
  if (!barrier_->all_finished()) {
    spdlog::warn("coordinator: not every member confirmed the end of the run within {} s",
                 options_.finish_timeout_s);
  }
}

// A verdict given before the start (a member refused at join, a join timeout) reaches only the
// readers matched with the coordinator's writers. The processes started with the run that had
// not yet matched them (the refused one included) would wait out their join timeout and end
// "no coordinator". The verdict and the announcement are kept for late readers (transient
// local): the coordinator stays until every start member confirmed the verdict or its
// participant matched both writers, or kReachBeforeStartS after the verdict. Members missing at
// a join timeout are not waited for.
void CoordinatorService::reach_members_before_start() {
  constexpr double kReachBeforeStartS = 5.0;
  const double deadline = now() + kReachBeforeStartS;
  std::vector<std::string> awaited;
  {
    std::lock_guard lock(mutex_);
    const auto missing = barrier_->missing_members();
    const bool timed_out = now() >= options_.barrier.join_timeout_s;
    for (const auto& member : options_.barrier.members) {
      if (!timed_out || announced_by_.contains(member) ||
          std::find(missing.begin(), missing.end(), member) == missing.end()) {
        awaited.push_back(member);
      }
    }
  }
  std::string unreached;
  for (const auto& member : awaited) {
    std::string guid;
    {
      std::unique_lock lock(mutex_);
      cv_.wait_for(lock, std::chrono::duration<double>(std::max(0.0, deadline - now())), [&] {
        return announced_by_.contains(member) || verdict_heard_by_.contains(member);
      });
      if (verdict_heard_by_.contains(member)) continue;
      if (const auto it = announced_by_.find(member); it != announced_by_.end()) guid = it->second;
    }
    GuidPrefix prefix;
    const bool reached =
        !guid.empty() && parse_guid_prefix(guid, prefix) &&
        control_writer_->wait_reached_by(prefix, std::max(0.0, deadline - now())) &&
        announce_writer_->wait_reached_by(prefix, std::max(0.0, deadline - now()));
    if (!reached) {
      unreached += (unreached.empty() ? "" : ", ") + member +
                   (guid.empty() ? " (not announced)" : " (participant " + guid + " not matched)");
    }
  }
  announce_writer_->wait_for_acknowledgments(1.0);
  if (!unreached.empty()) {
    spdlog::warn("coordinator: within {:g} s of the verdict, not reached: {}", kReachBeforeStartS,
                 unreached);
  }
}

int CoordinatorService::run(const std::atomic<bool>& interrupt) {
  t0_ = Clock::now();
  progress_every_ = std::max<std::int64_t>(1, options_.barrier.final_frame / 10);
  barrier_.emplace(options_.barrier, now());
  admission_ = proto::Admission(
      {options_.barrier.on_member_loss == proto::LossPolicy::recover, options_.claim_hold_s});
  spdlog::info("coordinator: run '{}' on domain {}, waiting for {} members", options_.dds.run_id,
               options_.dds.domain_id, options_.barrier.members.size());
  setup();

  bool interrupted = false;
  std::unique_lock lock(mutex_);
  write_status_locked("joining");
  advance_locked();
  while (!end_) {
    // Deadlines, real-time pacing and signals; everything else happens in the DDS callbacks.
    const double wake = std::min({next_wake_s_, admission_.next_deadline_s(), now() + 0.05});
    cv_.wait_for(lock, std::chrono::duration<double>(std::max(0.0, wake - now())));
    if (interrupt.load() && !interrupted) {
      interrupted = true;
      barrier_->on_interrupt("interrupted (signal to the coordinator)", now());
    }
    admission_.poll(now());  // claims held past their time are refused
    note_intrusions_locked();
    advance_locked();
  }

  const proto::Barrier::Action end = *end_;
  result_ = end.control;
  control_writer_->write(to_dds(end.control));
  if (end.kind == proto::Barrier::Action::Kind::stop) {
    const auto& s = end.control.stats;
    spdlog::info("coordinator: run completed: {} frames, {:.2f} s simulated in {:.3f} s "
                 "(real-time factor {:.3f})",
                 s.frames, s.sim_time_s, s.wall_time_s, s.real_time_factor);
  } else {
    spdlog::error("coordinator: run aborted: {}", end.control.reason);
  }
  const int code = end.kind == proto::Barrier::Action::Kind::stop ? kExitCompleted
                   : interrupted                                  ? kExitInterrupted
                                                                  : kExitAborted;
  const char* state = end.kind == proto::Barrier::Action::Kind::stop ? "completed"
                      : interrupted                                  ? "interrupted"
                                                                     : "aborted";
  write_status_locked(state, code);
  if (options_.on_verdict) options_.on_verdict(code);
  wait_for_finished(lock);
  const bool before_start = granted_frame_ < 0;
  lock.unlock();
  if (before_start && !interrupted) reach_members_before_start();
  control_writer_->wait_for_acknowledgments(1.0);
  if (end.kind == proto::Barrier::Action::Kind::stop) {
    // The run completed; a member that failed afterwards (while finishing) did not change that,
    // but it is named: its own exit status says it failed.
    lock.lock();
    failed_after_end_ = barrier_->failed_after_end();
    for (const auto& [member, why] : failed_after_end_) {
      spdlog::error("coordinator: {} failed after the run completed: {}", member, why);
    }
    lock.unlock();
  }
  {
    std::lock_guard guard(mutex_);
    write_status_locked(state, code, true);
  }
  return code;
}

void CoordinatorService::write_status_locked(const std::string& state, int exit_code, bool final) {
  if (options_.status_file.empty()) return;
  nlohmann::json j;
  j["run_id"] = options_.dds.run_id;
  j["scenario"] = options_.scenario_name;
  j["pid"] = static_cast<long>(::getpid());
  j["state"] = state;
  j["frame"] = granted_frame_;
  j["final_frame"] = options_.barrier.final_frame;
  j["recoveries"] = barrier_ ? barrier_->recoveries().size() : 0;
  // Each recovery, for tools that time them (the benchmarks): the frame a member was lost in,
  // the checkpoint rolled back to, the members lost and when it was decided (Unix time, s).
  j["recovery_list"] = nlohmann::json::array();
  if (barrier_) {
    const auto& list = barrier_->recoveries();
    for (std::size_t i = 0; i < list.size(); ++i) {
      nlohmann::json members = nlohmann::json::array();
      for (const auto& [member, why] : list[i].members) members.push_back(member);
      j["recovery_list"].push_back(
          {{"lost_in_frame", list[i].lost_in},
           {"rolled_back_to_frame", list[i].to_checkpoint},
           {"members", members},
           {"decided_unix_s", i < recovery_wall_s_.size() ? recovery_wall_s_[i] : 0.0}});
    }
  }
  // The members whose loss ended the run (none if it completed or recovered every loss).
  j["lost"] = nlohmann::json::array();
  if (barrier_) {
    for (const auto& [member, why] : barrier_->lost()) {
      j["lost"].push_back({{"member", member}, {"why", why}});
    }
  }
  // A completed run's timing, for tools that measure runs (the benchmarks) with or without a
  // recorder: frames completed, simulated and wall time, and their ratio.
  if (state == "completed") {
    const auto& s = result_.stats;
    // done_samples: the FrameDone and FrameDones samples received (a process with several
    // members sends one per frame for all of them).
    j["stats"] = {{"frames", s.frames},
                  {"sim_time_s", s.sim_time_s},
                  {"wall_time_s", s.wall_time_s},
                  {"real_time_factor", s.real_time_factor},
                  {"done_samples", done_samples_}};
  }
  j["reason"] = result_.reason;
  j["exit_code"] = exit_code;
  j["failed_after_end"] = failed_after_end_;
  j["final"] = final;
  try {
    std::filesystem::create_directories(std::filesystem::path(options_.status_file).parent_path());
    record::write_file_atomically(options_.status_file, j.dump(2) + "\n");
  } catch (const std::exception& e) {
    spdlog::error("coordinator: {}: {}", options_.status_file, e.what());
  }
}

}  // namespace syndds::dds
