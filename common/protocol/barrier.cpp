#include "protocol/barrier.hpp"

#include <algorithm>
#include <sstream>

#include "protocol/contact_bodies.hpp"

namespace syndds::proto {
namespace {

std::string join_names(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

}  // namespace

Barrier::Barrier(BarrierConfig config, double now_s) : config_(std::move(config)), created_s_(now_s) {
  for (const auto& m : config_.members) members_[m].active_from = 0;
  for (const auto& m : config_.late_members) members_[m].late = true;
  // A resumed run starts from a complete checkpoint: the first one to fall back on.
  if (config_.first_frame > 0) last_checkpoint_ = restored_checkpoint_ = config_.first_frame - 1;
}

std::string Barrier::on_join(const std::string& member, double now_s) {
  auto it = members_.find(member);
  if (it == members_.end()) {
    return "ignoring join of '" + member + "': not a member of this scenario";
  }
  Member& m = it->second;
  if (m.rejoining) {
    // A lost member restarted (on_member_loss: recover): back in with the rollback.
    m.rejoining = false;
    m.lost = false;
    m.joined = true;
    m.joined_at_s = now_s;
    return "";
  }
  if (m.joined) return "";  // repeated announcement (TRANSIENT_LOCAL) is harmless
  if (phase_ != Phase::joining && !m.late) {
    return "ignoring join of '" + member + "': the run has already started";
  }
  if (phase_ == Phase::stopped || phase_ == Phase::aborted) return "";
  m.joined = true;
  m.joined_at_s = now_s;
  return "";
}

std::string Barrier::on_config_mismatch(const std::string& member, const std::string& why,
                                        double now_s) {
  auto it = members_.find(member);
  if (it == members_.end()) {
    return "ignoring join of '" + member + "': not a member of this scenario";
  }
  if (it->second.late || phase_ != Phase::joining) {
    // The run (or its start) does not depend on it: refusing it harms nobody else.
    return "refusing member " + member + ": " + why;
  }
  if (!pending_abort_) pending_abort_ = "member " + member + " " + why;
  return "";
}

std::string Barrier::on_done(const FrameDoneMsg& done, double now_s) {
  auto it = members_.find(done.member_id);
  if (it == members_.end()) {
    return "ignoring done from '" + done.member_id + "': not a member of this scenario";
  }
  Member& m = it->second;
  if (!done.error.empty()) {
    if (phase_ == Phase::stopped) {
      // The run completed before it failed: not the run's failure, and not a loss either.
      if (m.joined && m.active_from >= 0 && !m.left) {
        failed_after_end_.emplace(done.member_id, done.error);
        m.finished = true;  // nothing more will come from it
      }
      return "";
    }
    if (phase_ == Phase::aborted || pending_abort_ || loss_abort_at_) return "";
    // While lost members are waited for, others may fail waiting for what the lost ones never
    // delivered: they end, are lost in turn and are recovered with the rest.
    if (recovering_) return "";
    if (m.left || m.active_from < 0) {
      // Not (or no longer) in the barrier: nobody waits for it, so its failure is its own.
      return "ignoring the failure of " + done.member_id + ", which is not in the barrier: " +
             done.error;
    }
    // A member that fails says why before it goes: that is the run's reason, not "lost".
    pending_abort_ = "member " + done.member_id + " failed: " + done.error;
    return "";
  }
  if (m.left) return "ignoring done from '" + done.member_id + "': member has left the run";
  if (!done.finished && !active(m)) return "";  // a late joiner not yet taking part
  if (done.finished) {
    m.finished = true;
    return "";
  }
  if (phase_ != Phase::running) return "";
  // A done of an epoch that was rolled back answers a grant that no longer counts.
  if (done.epoch != epoch_ || recovering_) return "";
  if (done.frame != frame_) {
    if (done.frame < frame_) return "";  // stale duplicate
    return "ignoring done from '" + done.member_id + "' for frame " + std::to_string(done.frame) +
           ": frame " + std::to_string(frame_) + " is current";
  }
  if (m.done) return "";
  m.done = true;
  m.published = done.published;
  m.body.clear();
  m.checkpoint_bytes = done.checkpoint_bytes;
  const double response = now_s - grant_s_;
  m.response_sum_s += response;
  m.response_max_s = std::max(m.response_max_s, response);
  m.compute_sum_s += done.compute_s;
  ++m.responses;
  last_done_member_ = done.member_id;
  // A contact body is a vehicle member's own: vehicle/<id> reporting vehicle <id>, at most one.
  // Another is dropped (the done still counts): nobody may move someone else's vehicle.
  if (!done.body.empty()) {
    if (done.body.size() > 1 || done.member_id != "vehicle/" + done.body.front().vehicle_id) {
      return "dropping the contact body in done from '" + done.member_id + "' (vehicle '" +
             done.body.front().vehicle_id + "'): only vehicle/<id> reports <id>'s, once";
    }
    m.body = done.body;
  }
  return "";
}

void Barrier::on_member_lost(const std::string& member, const std::string& why, double now_s) {
  auto it = members_.find(member);
  if (it == members_.end() || it->second.lost) return;
  if (phase_ == Phase::stopped || phase_ == Phase::aborted) {
    // Not a loss of the run: its stats were sent with the end. Whether it confirmed the end
    // is decided when asked (failed_after_end): its confirmation may still be on its way.
    if (phase_ == Phase::stopped) {
      lost_after_end_.emplace(member, why);
    } else {
      it->second.lost = true;
    }
    return;
  }
  it->second.lost = true;
  if (it->second.late && it->second.active_from < 0) {
    it->second.joined = false;  // never took part: it may announce itself again
    it->second.lost = false;
    return;
  }
  if (config_.on_member_loss == LossPolicy::recover && phase_ == Phase::running &&
      !loss_abort_at_ && !pending_abort_) {
    std::string cannot;
    if (last_checkpoint_ < 0) {
      cannot = "no complete checkpoint to recover from yet";
    } else if (static_cast<int>(recoveries_.size()) >= config_.max_recoveries) {
      cannot = "the run recovered " + std::to_string(recoveries_.size()) +
               " times already (coordinator.max_recoveries)";
    }
    if (cannot.empty()) {
      // Every member rolls back to the last complete checkpoint once the lost ones announce
      // themselves again (restarted by the launcher or by hand); nothing is granted meanwhile.
      if (!recovering_) {
        recovering_ = Recovery{frame_, last_checkpoint_, {}};
        rejoin_deadline_ = now_s + config_.rejoin_timeout_s;
      }
      recovering_->members.emplace_back(member, why);
      it->second.rejoining = true;
      it->second.joined = false;
      return;
    }
    lost_.emplace_back(member, why + "; cannot recover: " + cannot);
    if (!loss_abort_at_) loss_abort_at_ = now_s + kLossGatherS;
    return;
  }
  if (config_.on_member_loss != LossPolicy::continue_run || phase_ == Phase::joining) {
    if (!pending_abort_) {
      lost_.emplace_back(member, why);
      if (!loss_abort_at_) loss_abort_at_ = now_s + kLossGatherS;
    }
  } else {
    it->second.left = true;
    departed_.push_back(member);
  }
}

void Barrier::on_interrupt(const std::string& why, double now_s) {
  if (!pending_abort_ && !loss_abort_at_) pending_abort_ = why;
}

// A member that died without leaving (abort policy) never counts as done: a frame is complete
// only when every member still in the barrier reported it.
bool Barrier::everyone_done() const {
  for (const auto& [name, m] : members_) {
    if (active(m) && !m.left && !m.done) return false;
  }
  return true;
}

std::vector<std::string> Barrier::admit_joiners(std::int64_t frame, double now_s) {
  std::vector<std::string> out;
  for (auto& [name, m] : members_) {
    if (m.late && m.joined && m.active_from < 0 && !m.lost &&
        (frame == 0 || now_s - m.joined_at_s >= config_.late_join_delay_s)) {
      m.active_from = frame + 1;
      out.push_back(name);
    }
  }
  return out;
}

std::vector<VehicleBodyMsg> Barrier::collect_bodies() const {
  // Like the manifest: a member that left is not passed on (its vehicle is no longer felt).
  std::vector<VehicleBodyMsg> all;
  for (const auto& [name, m] : members_) {
    if (!active(m) || m.left) continue;
    all.insert(all.end(), m.body.begin(), m.body.end());
  }
  return select_contact_bodies(std::move(all), config_.heartbeat_s);
}

Manifest Barrier::collect_manifest() const {
  Manifest out;
  for (const auto& [name, m] : members_) {
    // A member that left (continue policy) is not announced: its samples may never arrive.
    if (!m.done || m.left) continue;
    out.insert(out.end(), m.published.begin(), m.published.end());
  }
  std::sort(out.begin(), out.end(), [](const TopicCount& a, const TopicCount& b) {
    return std::tie(a.topic, a.key, a.writer) < std::tie(b.topic, b.key, b.writer);
  });
  return out;
}

Barrier::Action Barrier::abort_with(const std::string& reason, double now_s) {
  if (phase_ == Phase::running && everyone_done() && last_completed_ != frame_) {
    last_completed_ = frame_;
    last_manifest_ = collect_manifest();
  }
  phase_ = Phase::aborted;
  end_s_ = now_s;
  Action a;
  a.kind = Action::Kind::abort;
  a.control.status = RunStatus::aborted;
  a.control.reason = reason;
  a.control.final_frame = last_completed_;
  // The last complete frame's samples: members that have not consumed them yet (the recorder
  // in the middle of the next frame, or nobody yet) keep that frame too; the others skip it.
  a.control.final_manifest = last_manifest_;
  a.control.stats = stats(now_s);
  announced_end_ = true;
  return a;
}

// "member A lost: why", or for several "members A, B lost: why" (the distinct reasons joined).
std::string Barrier::loss_reason() const {
  std::string names, whys;
  for (const auto& [member, why] : lost_) {
    names += (names.empty() ? "" : ", ") + member;
    if (whys.find(why) == std::string::npos) whys += (whys.empty() ? "" : "; ") + why;
  }
  return (lost_.size() == 1 ? "member " : "members ") + names + " lost: " + whys;
}

Barrier::Action Barrier::poll(double now_s) {
  Action wait;
  wait.kind = Action::Kind::wait;
  if (phase_ == Phase::stopped || phase_ == Phase::aborted) {
    wait.wake_at_s = now_s + 1.0;
    return wait;
  }
  if (pending_abort_) return abort_with(*pending_abort_, now_s);
  if (loss_abort_at_) {
    if (now_s < *loss_abort_at_) {
      wait.wake_at_s = *loss_abort_at_;
      return wait;
    }
    return abort_with(loss_reason(), now_s);
  }

  if (phase_ == Phase::joining) {
    const auto missing = missing_members();
    if (missing.empty()) {
      phase_ = Phase::running;
      // A resumed run starts after its checkpoint; every member steps that frame with the
      // inputs saved in its checkpoint, so the first grant announces none.
      frame_ = config_.first_frame;
      last_completed_ = frame_ - 1;
      grant_s_ = first_grant_s_ = now_s;
      Action a;
      a.kind = Action::Kind::grant;
      a.grant.frame = frame_;
      a.grant.sim_time_s = static_cast<double>(frame_) * config_.heartbeat_s;
      // Late members already here start with the next frame.
      if (frame_ < config_.final_frame) a.grant.joiners = admit_joiners(frame_, now_s);
      return a;
    }
    const double deadline = created_s_ + config_.join_timeout_s;
    if (now_s >= deadline) {
      std::ostringstream msg;
      msg << "join timeout after " << config_.join_timeout_s << " s: missing "
          << join_names(missing);
      return abort_with(msg.str(), now_s);
    }
    wait.wake_at_s = deadline;
    return wait;
  }

  // running
  if (recovering_) return poll_recovering(now_s);
  if (!everyone_done()) {
    const double deadline = grant_s_ + config_.frame_timeout_s;
    if (now_s >= deadline) {
      std::ostringstream msg;
      msg << "frame " << frame_ << " missed its " << config_.frame_timeout_s
          << " s deadline; still waiting for " << join_names(pending_members());
      return abort_with(msg.str(), now_s);
    }
    wait.wake_at_s = deadline;
    return wait;
  }

  // Everyone is done with frame_: account, then grant the next frame or stop.
  if (!last_done_member_.empty()) {
    ++members_[last_done_member_].slowest;
    last_done_member_.clear();
  }
  last_completed_ = frame_;
  const Manifest manifest = collect_manifest();
  std::vector<VehicleBodyMsg> bodies = collect_bodies();
  last_manifest_ = manifest;
  if (rolling_back_) {
    rolling_back_ = false;  // every member restored the checkpoint of frame_: nothing was due
  } else {
    note_checkpoint();
  }
  if (frame_ >= config_.final_frame) {
    phase_ = Phase::stopped;
    end_s_ = now_s;
    Action a;
    a.kind = Action::Kind::stop;
    a.control.status = RunStatus::completed;
    a.control.final_frame = frame_;
    a.control.final_manifest = manifest;
    a.control.stats = stats(now_s);
    announced_end_ = true;
    return a;
  }
  if (config_.realtime) {
    const double due =
        first_grant_s_ + static_cast<double>(frame_ + 1 - config_.first_frame) * config_.heartbeat_s;
    if (now_s < due) {
      wait.wake_at_s = due;
      return wait;
    }
  }
  ++frame_;
  grant_s_ = now_s;
  for (auto& [name, m] : members_) {
    m.done = false;
    m.published.clear();
    m.body.clear();
    m.checkpoint_bytes = 0;
  }
  Action a;
  a.kind = Action::Kind::grant;
  a.grant.frame = frame_;
  a.grant.sim_time_s = static_cast<double>(frame_) * config_.heartbeat_s;
  a.grant.epoch = epoch_;
  a.grant.manifest = manifest;
  a.grant.bodies = std::move(bodies);
  a.grant.departed = std::move(departed_);
  departed_.clear();
  if (frame_ < config_.final_frame) a.grant.joiners = admit_joiners(frame_, now_s);
  return a;
}

void Barrier::note_checkpoint() {
  // Members write the checkpoint of frame K before they step K + 1, but not the one the run
  // resumed or rolled back to: it exists.
  const std::int64_t of = frame_ - 1;
  if (!checkpoint_due(of, config_.checkpoint_every) || of == restored_checkpoint_) return;
  CheckpointReport r;
  r.frame = of;
  for (const auto& [name, m] : members_) {
    if (!active(m) || m.left) continue;
    if (m.checkpoint_bytes > 0) {
      r.members.emplace_back(name, m.checkpoint_bytes);
    } else {
      r.missing.push_back(name);
    }
  }
  if (r.missing.empty()) last_checkpoint_ = of;
  checkpoint_ = std::move(r);
}

std::vector<std::string> Barrier::rejoining_members() const {
  std::vector<std::string> out;
  for (const auto& [name, m] : members_) {
    if (m.rejoining) out.push_back(name);
  }
  return out;
}

Barrier::Action Barrier::poll_recovering(double now_s) {
  const auto waiting = rejoining_members();
  if (!waiting.empty()) {
    if (now_s >= *rejoin_deadline_) {
      std::ostringstream msg;
      msg << join_names(waiting) << " lost (";
      for (const auto& [member, why] : recovering_->members) msg << member << ": " << why << "; ";
      msg << "the run was to roll back to the checkpoint of frame " << recovering_->to_checkpoint
          << ") and did not announce itself again within " << config_.rejoin_timeout_s << " s";
      return abort_with(msg.str(), now_s);
    }
    Action wait;
    wait.kind = Action::Kind::wait;
    wait.wake_at_s = *rejoin_deadline_;
    return wait;
  }
  // Everyone is back: every member restores its checkpoint of frame C and reports frame C
  // done (in the new epoch); only then is C + 1 granted, which every member steps with the
  // inputs saved in its checkpoint. Two steps, so that no member publishes a sample of the new
  // epoch while another still holds the old one's frames as taken.
  Action a;
  a.kind = Action::Kind::grant;
  for (const auto& [member, why] : recovering_->members) a.grant.rejoined.push_back(member);
  recoveries_.push_back(std::move(*recovering_));
  recovering_.reset();
  rejoin_deadline_.reset();
  checkpoint_.reset();
  ++epoch_;
  restored_checkpoint_ = last_checkpoint_;
  frame_ = last_checkpoint_;
  last_completed_ = last_checkpoint_ - 1;
  rolling_back_ = true;
  grant_s_ = now_s;
  // Realtime pacing goes on from here.
  first_grant_s_ = now_s - static_cast<double>(frame_ - config_.first_frame) * config_.heartbeat_s;
  for (auto& [name, m] : members_) {
    m.done = false;
    m.published.clear();
    m.body.clear();
    m.checkpoint_bytes = 0;
  }
  a.grant.frame = frame_;
  a.grant.sim_time_s = static_cast<double>(frame_) * config_.heartbeat_s;
  a.grant.epoch = epoch_;
  a.grant.rollback = true;
  return a;
}

std::optional<CheckpointReport> Barrier::take_checkpoint() {
  auto r = std::move(checkpoint_);
  checkpoint_.reset();
  return r;
}

std::vector<std::string> Barrier::missing_members() const {
  std::vector<std::string> out;
  for (const auto& [name, m] : members_) {
    if (!m.joined && !m.late) out.push_back(name);
  }
  return out;
}

std::vector<std::string> Barrier::pending_members() const {
  std::vector<std::string> out;
  for (const auto& [name, m] : members_) {
    if (active(m) && !m.left && !m.done) out.push_back(name);
  }
  return out;
}

std::map<std::string, std::string> Barrier::failed_after_end() const {
  std::map<std::string, std::string> out = failed_after_end_;
  for (const auto& [name, why] : lost_after_end_) {
    const Member& m = members_.at(name);
    if (m.joined && m.active_from >= 0 && !m.left && !m.finished && !out.contains(name)) {
      out[name] = "ended without confirming the end of the run (" + why + ")";
    }
  }
  return out;
}

bool Barrier::all_finished() const {
  for (const auto& [name, m] : members_) {
    if (m.joined && m.active_from >= 0 && !m.lost && !m.finished &&
        !lost_after_end_.contains(name)) {
      return false;
    }
  }
  return true;
}

RunStatsMsg Barrier::stats(double now_s) const {
  RunStatsMsg s;
  s.frames = static_cast<std::uint64_t>(last_completed_ + 1);
  s.final_frame = last_completed_;
  s.sim_time_s = last_completed_ > 0 ? static_cast<double>(last_completed_) * config_.heartbeat_s : 0.0;
  const double end = (phase_ == Phase::stopped || phase_ == Phase::aborted) ? end_s_ : now_s;
  s.wall_time_s = phase_ == Phase::joining ? 0.0 : end - first_grant_s_;
  s.real_time_factor = s.sim_time_s > 0.0 ? s.wall_time_s / s.sim_time_s : 0.0;
  for (const auto& [name, m] : members_) {
    MemberStatsMsg ms;
    ms.member_id = name;
    if (m.responses > 0) {
      ms.mean_response_s = m.response_sum_s / static_cast<double>(m.responses);
      ms.mean_compute_s = m.compute_sum_s / static_cast<double>(m.responses);
    }
    ms.max_response_s = m.response_max_s;
    ms.slowest_count = m.slowest;
    ms.lost = m.lost;
    s.members.push_back(ms);
  }
  return s;
}

}  // namespace syndds::proto
