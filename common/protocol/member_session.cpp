#include "protocol/member_session.hpp"

#include "protocol/admission.hpp"

#include <algorithm>
#include <sstream>

namespace syndds::proto {
namespace {

std::string seconds(double s) {
  std::ostringstream out;
  out << s;
  return out.str();
}

}  // namespace

MemberSession::MemberSession(std::vector<Subscription> subscriptions, MemberSessionConfig config,
                             double now_s)
    : config_(std::move(config)), inbox_(std::move(subscriptions)), created_s_(now_s) {}

std::string MemberSession::on_coordinator(const MemberAnnounceMsg& a, double now_s) {
  if (!coordinator_) {
    coordinator_ = a;
    return "";
  }
  if (coordinator_->participant_guid == a.participant_guid) {
    // The same coordinator again: its newest word on who is admitted (one writer: in order).
    coordinator_ = a;
    return "";
  }
  const std::string why = "a second coordinator (pid " + std::to_string(a.pid) + " on " + a.host +
                          ") announced run '" + a.run_id + "'";
  on_failure(why, now_s);
  return why;
}

void MemberSession::resume(FrameSamples inputs) {
  if (config_.resume_frame < 0) throw ProtocolError("MemberSession::resume without resume_frame");
  next_frame_ = config_.resume_frame + 1;
  resumed_inputs_ = std::move(inputs);
}

void MemberSession::on_rolled_back(FrameSamples inputs, double now_s) {
  rolling_back_ = false;
  resumed_inputs_ = std::move(inputs);
}

void MemberSession::on_grant(FrameGrantMsg grant, double now_s) {
  const Manifest manifest = std::move(grant.manifest);
  on_grant(std::move(grant), manifest, now_s);
}

void MemberSession::on_grant(FrameGrantMsg grant, const Manifest& manifest, double now_s) {
  // The manifest names every member's samples; this member waits for and takes only those it
  // subscribes to, so it keeps only their entries (checked for every sample that arrives).
  grant.manifest = inbox_.needed(manifest);
  grants_.push_back(std::move(grant));
}

bool MemberSession::sample_may_unblock() const {
  // Only the running member's wait for the inputs of its next granted frame can end with a
  // sample; anything unusual (joining, finishing, a rollback or late-join grant first in line)
  // is left to poll(), as before.
  if (phase_ != Phase::running || control_ || !failure_.empty() || interrupted_s_) return true;
  if (grants_.empty()) return false;  // the grant wakes the member when it comes
  const FrameGrantMsg& front = grants_.front();
  if (!admitted_ || front.rollback || front.epoch != epoch_ || front.frame != next_frame_ ||
      resumed_inputs_ || config_.skip_data_barrier) {
    return true;
  }
  return inbox_.complete(front.frame - 1, front.manifest);
}

void MemberSession::on_control(RunControlMsg control, double now_s) {
  if (control_) return;  // the verdict is given once; later copies are replays
  control_ = std::move(control);
  control_s_ = now_s;
}

void MemberSession::on_coordinator_lost(double now_s) { coordinator_lost_ = true; }

void MemberSession::on_interrupt(double now_s) {
  if (!interrupted_s_) interrupted_s_ = now_s;
}

void MemberSession::on_failure(const std::string& why, double now_s) {
  if (failure_.empty()) failure_ = why;
}

void MemberSession::on_stepped(std::int64_t frame, const std::string& error, double now_s) {
  stepping_ = false;
  next_frame_ = frame + 1;
  if (!error.empty()) on_failure("frame " + std::to_string(frame) + ": " + error, now_s);
}

MemberSession::Action MemberSession::wait_until(double t) const {
  Action a;
  a.kind = Action::Kind::wait;
  a.wake_at_s = t;
  return a;
}

MemberSession::Action MemberSession::finish(RunControlMsg control, Outcome outcome,
                                            double now_s) {
  phase_ = Phase::ended;
  Action a;
  a.kind = Action::Kind::finish;
  a.control = std::move(control);
  a.outcome = outcome;
  return a;
}

// This member ends the run on its own: the agent learns why, and a failure (not an interrupt)
// is reported to the coordinator so that the run's one-line reason names the cause.
MemberSession::Action MemberSession::fail(const std::string& why, Outcome outcome,
                                          double now_s) {
  RunControlMsg c;
  c.status = RunStatus::aborted;
  c.reason = why;
  Action a = finish(std::move(c), outcome, now_s);
  if (outcome == Outcome::failed) {
    a.error = why;
    a.error_frame = next_frame_;
  }
  return a;
}

std::string MemberSession::differing_files(const MemberAnnounceMsg& coordinator) const {
  const std::string d = config_file_differences(config_.config_files, coordinator.config_files);
  return d.empty() ? std::string(kFingerprintHint)
                   : "files that differ (here, on the coordinator's host): " + d;
}

std::string MemberSession::check_coordinator() const {
  const auto& c = *coordinator_;
  const auto& expected = c.expected_members;
  if (std::find(expected.begin(), expected.end(), config_.member_id) == expected.end()) {
    return "the coordinator of run '" + config_.run_id + "' does not expect member " +
           config_.member_id;
  }
  if (c.config_fingerprint != config_.config_fingerprint) {
    return "scenario mismatch: the coordinator (host " + c.host +
           ") loaded a different scenario or overrides (fingerprint " +
           fingerprint_hex(c.config_fingerprint) + ", mine " +
           fingerprint_hex(config_.config_fingerprint) + "); " + differing_files(c);
  }
  if (c.protocol_version != kProtocolVersion) {
    return "protocol version mismatch: coordinator " + std::to_string(c.protocol_version) +
           ", mine " + std::to_string(kProtocolVersion);
  }
  if (!c.build_id.empty() && !config_.build_id.empty() && c.build_id != config_.build_id) {
    return "build mismatch: the coordinator (host " + c.host + ") runs syndds build " +
           c.build_id + ", this process build " + config_.build_id +
           " (other physics or protocol sources: build every host from the same commit)";
  }
  return "";
}

bool MemberSession::confirmed() const {
  if (config_.participant_guid.empty()) return true;  // no DDS identity (tests of other rules)
  const std::string mine = config_.member_id + " " + config_.participant_guid;
  const auto& a = coordinator_->admitted;
  return std::find(a.begin(), a.end(), mine) != a.end();
}

std::string MemberSession::refusal() const {
  for (const auto& entry : coordinator_->refused) {
    std::string member, participant, why;
    if (!split_member_entry(entry, member, participant, &why)) continue;
    if (member == config_.member_id && participant == config_.participant_guid) {
      return "refused by the coordinator as " + member + ": " + why;
    }
  }
  return "";
}

double MemberSession::gather_deadline() const {
  double deadline = control_s_ + config_.final_timeout_s;
  if (interrupted_s_) {
    // Interrupted: the verdict is still worth its complete frame, but not a long wait.
    deadline = std::min(deadline, std::max(control_s_, *interrupted_s_) + config_.interrupt_grace_s);
  }
  return deadline;
}

MemberSession::Action MemberSession::poll_finishing(double now_s) {
  RunControlMsg control = *control_;
  Outcome outcome = control.status == RunStatus::completed ? Outcome::completed
                                                           : Outcome::aborted;
  if (interrupted_s_ && outcome == Outcome::aborted) outcome = Outcome::interrupted;
  const bool gather = control.final_frame >= 0 && !control.final_manifest.empty() &&
                      control.final_frame > inbox_.last_taken_frame();
  FrameSamples final_inputs;
  if (gather) {
    if (!inbox_.complete(control.final_frame, control.final_manifest)) {
      if (now_s < gather_deadline() && !coordinator_lost_) return wait_until(gather_deadline());
      // Never hand out a partial frame: the agent ends with the last complete one, and says so.
      const std::string missing =
          inbox_.describe_missing(control.final_frame, control.final_manifest);
      control.status = RunStatus::aborted;
      control.reason = (control.reason.empty() ? "" : control.reason + "; ") + "final frame " +
                       std::to_string(control.final_frame) + " incomplete at " +
                       config_.member_id + ": " + missing;
      outcome = Outcome::failed;
    } else {
      final_inputs = inbox_.take(control.final_frame, control.final_manifest);
    }
  }
  Action a = finish(std::move(control), outcome, now_s);
  a.inputs = std::move(final_inputs);
  a.confirm = true;
  return a;
}

MemberSession::Action MemberSession::poll(double now_s) {
  if (phase_ == Phase::ended || stepping_ || rolling_back_) return wait_until(now_s + 1.0);

  if (phase_ == Phase::joining) {
    if (interrupted_s_) return fail("interrupted", Outcome::interrupted, now_s);
    if (!failure_.empty()) return fail(failure_, Outcome::failed, now_s);
    if (!coordinator_) {
      const double deadline = created_s_ + config_.join_timeout_s;
      if (now_s >= deadline) {
        return fail("no coordinator for run '" + config_.run_id + "' on " + config_.transport +
                        " within " + std::to_string(static_cast<int>(config_.join_timeout_s)) +
                        " s",
                    Outcome::failed, now_s);
      }
      return wait_until(deadline);
    }
    if (const std::string why = check_coordinator(); !why.empty()) {
      return fail(why, Outcome::failed, now_s);
    }
    phase_ = Phase::running;
    // A resumed member took part when its checkpoint was written: it is in from the start.
    admitted_ = (!config_.late_join && !config_.rejoin) || resumed_inputs_.has_value();
    Action a;
    a.kind = Action::Kind::joined;
    return a;
  }

  // The coordinator's verdict wins over everything still pending here (a grant waiting for
  // its inputs, an interrupt waiting for the verdict).
  if (control_) {
    phase_ = Phase::finishing;
    return poll_finishing(now_s);
  }
  if (!failure_.empty()) return fail(failure_, Outcome::failed, now_s);
  if (interrupted_s_) {
    // Interrupted (the coordinator, interrupted by the same Ctrl-C or hang-up, is about to
    // abort): start no frame, and wait a little for its verdict, which names the last complete
    // frame; the recorder then still keeps it.
    const double deadline = *interrupted_s_ + config_.interrupt_grace_s;
    if (now_s < deadline && !coordinator_lost_) return wait_until(deadline);
    return fail("interrupted", Outcome::interrupted, now_s);
  }
  if (coordinator_lost_) {
    return fail("the coordinator was lost (its process exited or stopped answering)",
                Outcome::failed, now_s);
  }

  // Admission: grants are acted on only once the coordinator names this participant as this
  // member; a claimant it refused ends (another participant is this member).
  if (!owner_confirmed_) {
    if (const std::string why = refusal(); !why.empty()) {
      RunControlMsg c;
      c.status = RunStatus::aborted;
      c.reason = why;
      return finish(std::move(c), Outcome::refused, now_s);
    }
    if (!confirmed()) return wait_until(now_s + config_.input_timeout_s);
    owner_confirmed_ = true;
  }

  // A rollback (on_member_loss: recover) voids every grant before it: whatever this member
  // was waiting for in the old epoch will not come, or comes again identical.
  for (auto it = grants_.rbegin(); it != grants_.rend(); ++it) {
    if (it->rollback && it->epoch > epoch_) {
      grants_.erase(grants_.begin(), std::prev(it.base()));
      break;
    }
  }
  while (!grants_.empty()) {
    FrameGrantMsg& front = grants_.front();
    if (front.epoch < epoch_) {  // an old epoch's grant, replayed
      grants_.pop_front();
      continue;
    }
    if (front.rollback && front.epoch > epoch_) {
      const auto& r = front.rejoined;
      const bool named = std::any_of(r.begin(), r.end(), [&](const std::string& e) {
        return e.substr(0, e.find(' ')) == config_.member_id;
      });
      if (!admitted_ && !(config_.rejoin && named)) {
        grants_.pop_front();  // a late joiner not in yet: not its business
        continue;
      }
      // Every member restores its checkpoint of the granted frame and reports it done; the next
      // frame is then stepped with the inputs saved there.
      admitted_ = true;
      epoch_ = front.epoch;
      next_frame_ = front.frame + 1;
      inbox_.reset(front.frame);
      waiting_frame_ = -1;
      rolling_back_ = true;
      Action a;
      a.kind = Action::Kind::rollback;
      a.rollback_frame = front.frame;
      a.rejoined = std::move(front.rejoined);
      grants_.pop_front();
      return a;
    }
    if (!admitted_ && config_.rejoin) {  // restarted: waits for the rollback naming it
      grants_.pop_front();
      continue;
    }
    if (!admitted_) {
      // A late joiner starts with the frame after the grant that names it; grants before that
      // (also old ones replayed by TRANSIENT_LOCAL) are not its business.
      const auto& j = front.joiners;
      if (std::find(j.begin(), j.end(), config_.member_id) != j.end()) {
        admitted_ = true;
        next_frame_ = front.frame + 1;
      }
      grants_.pop_front();
      continue;
    }
    if (front.frame < next_frame_) {  // duplicate
      grants_.pop_front();
      continue;
    }
    if (front.frame > next_frame_) {
      return fail("protocol error: granted frame " + std::to_string(front.frame) +
                      " while frame " + std::to_string(next_frame_) + " was expected",
                  Outcome::failed, now_s);
    }
    const std::int64_t input_frame = front.frame - 1;
    if (resumed_inputs_) {
      Action a;
      a.kind = Action::Kind::step;
      a.context = FrameContext{front.frame, front.sim_time_s, config_.heartbeat_s, front.joiners,
                               front.departed, front.intrusions};
      a.inputs = std::move(*resumed_inputs_);
      resumed_inputs_.reset();
      grants_.pop_front();
      stepping_ = true;
      return a;
    }
    if (!config_.skip_data_barrier && !inbox_.complete(input_frame, front.manifest)) {
      // The data barrier: the announced samples of frame - 1 are not all here yet.
      if (waiting_frame_ != front.frame) {
        waiting_frame_ = front.frame;
        waiting_since_s_ = now_s;
      }
      const double deadline = waiting_since_s_ + config_.input_timeout_s;
      if (now_s >= deadline) {
        std::ostringstream why;
        why << "frame " << front.frame << ": announced inputs missing after "
            << seconds(config_.input_timeout_s)
            << " s: " << inbox_.describe_missing(input_frame, front.manifest);
        return fail(why.str(), Outcome::failed, now_s);
      }
      return wait_until(deadline);
    }
    Action a;
    a.kind = Action::Kind::step;
    a.context = FrameContext{front.frame, front.sim_time_s, config_.heartbeat_s, front.joiners,
                             front.departed, front.intrusions};
    a.inputs = inbox_.take(input_frame, front.manifest);
    a.inputs.contact_bodies = std::move(front.bodies);
    grants_.pop_front();
    waiting_frame_ = -1;
    stepping_ = true;
    return a;
  }
  return wait_until(now_s + config_.input_timeout_s);
}

}  // namespace syndds::proto
