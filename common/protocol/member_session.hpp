#pragma once
// The member side of the time protocol as a pure state machine, the counterpart of Barrier:
// events in (the coordinator's announcement, grants, run control, data samples, the
// coordinator lost, an interrupt, a failure), decisions out (step frame k with these inputs,
// finish the run with this verdict). Time is passed in (seconds on any monotonic clock), so
// every rule is unit-testable without DDS or threads. services/dds/member_runtime drives it:
// it owns the DDS entities, checks who wrote what, runs the agent and publishes.
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "protocol/agent.hpp"
#include "protocol/frame_inbox.hpp"
#include "protocol/messages.hpp"

namespace syndds::proto {

struct MemberSessionConfig {
  std::string member_id;
  std::string run_id;
  std::string transport;          // where the coordinator was looked for, e.g. "DDS domain 7"
  std::uint64_t config_fingerprint = 0;
  double heartbeat_s = 0.01;      // frame length, from the scenario
  double join_timeout_s = 30.0;   // waiting for the coordinator's announcement
  double input_timeout_s = 10.0;  // waiting for announced samples once a frame is granted
  double final_timeout_s = 5.0;   // gathering the final frame's samples after the run ended
  double interrupt_grace_s = 2.0; // after an interrupt: waiting for the coordinator's verdict
  bool late_join = false;         // may join a run under way: starts after the grant naming it
  bool skip_data_barrier = false; // test knob: start frames without waiting for announced data
  std::int64_t resume_frame = -1; // >= 0: resumed from the checkpoint of this frame (resume())
  bool rejoin = false;            // restarted after it was lost (on_member_loss: recover): takes
                                  // part from the rollback grant that names it
  std::string build_id;           // this program's build (core/build_identity.hpp); "": unchecked
  std::vector<std::string> config_files;  // "ROLE HASH" of the fingerprinted files (names the
                                          // file that differs on a mismatch)
  std::string participant_guid;   // this member's DDS participant: it acts on grants only once
                                  // the coordinator admitted it ("" in tests: no admission step)
};

class MemberSession {
 public:
  enum class Phase { joining, running, finishing, ended };
  /// How this member's run ended (the runtime maps it onto the documented exit codes).
  enum class Outcome {
    completed,
    aborted,
    failed,
    interrupted,
    refused,  // the coordinator refused this participant as this member (another one is it)
  };

  struct Action {
    enum class Kind { wait, joined, rollback, step, finish };
    Kind kind = Kind::wait;
    double wake_at_s = 0.0;  // wait: call poll() again by then even without events
    // rollback: restore the agent from its checkpoint of `rollback_frame`, call
    // on_rolled_back() with the inputs saved there (or on_failure()), report the frame done.
    std::int64_t rollback_frame = -1;
    std::vector<std::string> rejoined;  // "MEMBER PARTICIPANT_GUID" of the restarted members
    // step: run the agent on `context` with `inputs`, publish, report done, then on_stepped().
    FrameContext context;
    FrameSamples inputs;     // step: samples stamped frame - 1; finish: the final inputs
    // finish: tell the agent `control` with `inputs`, then end with `outcome`.
    RunControlMsg control;
    Outcome outcome = Outcome::completed;
    std::string error;       // finish: this member's own failure, to report to the coordinator
                             // (FrameDone with error) before anything else
    std::int64_t error_frame = 0;
    bool confirm = false;    // finish: the coordinator's verdict arrived; reply FrameDone
                             // (finished) once the agent finished
  };

  MemberSession(std::vector<Subscription> subscriptions, MemberSessionConfig config,
                double now_s);

  /// Events. on_coordinator returns a non-empty message when the announcement is refused.
  std::string on_coordinator(const MemberAnnounceMsg& announce, double now_s);
  void on_grant(FrameGrantMsg grant, double now_s);
  /// The same, with the grant's manifest apart (grant.manifest is ignored): a process that
  /// decodes a grant once for several members hands each the manifest by reference, and each
  /// keeps only its own entries.
  void on_grant(FrameGrantMsg grant, const Manifest& manifest, double now_s);
  void on_control(RunControlMsg control, double now_s);
  void on_coordinator_lost(double now_s);
  /// The coordinator's process exited, or its DDS lease expired: nothing sent to it is read.
  bool coordinator_lost() const { return coordinator_lost_; }
  void on_interrupt(double now_s);
  /// This member cannot go on (a malformed sample, a failed step); the first reason wins.
  void on_failure(const std::string& why, double now_s);
  /// The step handed out by poll() ended; `error` is empty when it succeeded.
  void on_stepped(std::int64_t frame, const std::string& error, double now_s);
  /// A data sample whose writer was checked. True when poll() may now decide something new
  /// (the caller wakes the thread that polls): false when the inbox does not keep the sample,
  /// and false while the member waits for a grant or for more of a granted frame's inputs, so
  /// that a member receiving many samples per frame is woken once, not once per sample.
  template <typename Msg>
  bool add(Msg sample) {
    return inbox_.add(std::move(sample)) && sample_may_unblock();
  }

  /// A member resumed from its checkpoint of config.resume_frame: the first frame it steps is
  /// the next one, with `inputs` (saved in the checkpoint) instead of samples from the network.
  void resume(FrameSamples inputs);
  /// The rollback handed out by poll() is done: the agent holds its checkpointed state and
  /// steps the granted frame with `inputs`.
  void on_rolled_back(FrameSamples inputs, double now_s);
  /// The epoch of the grants this member answers (dones carry it).
  std::uint32_t epoch() const { return epoch_; }

  /// The next decision. joined/step/finish are returned once; after finish poll() says wait.
  Action poll(double now_s);

  Phase phase() const { return phase_; }
  const std::optional<MemberAnnounceMsg>& coordinator() const { return coordinator_; }
  bool admitted() const { return admitted_; }
  std::int64_t next_frame() const { return next_frame_; }
  const FrameInbox& inbox() const { return inbox_; }

 private:
  bool sample_may_unblock() const;
  Action finish(RunControlMsg control, Outcome outcome, double now_s);
  Action fail(const std::string& why, Outcome outcome, double now_s);
  Action wait_until(double t) const;
  /// The coordinator's verdict with the final inputs, once they are complete or given up on.
  Action poll_finishing(double now_s);
  /// Latest time to gather the final frame: bounded shorter after an interrupt.
  double gather_deadline() const;
  /// Why the announced coordinator cannot be followed ("" when it can).
  std::string check_coordinator() const;
  /// The files that make the fingerprints differ, or the hint how to find them.
  std::string differing_files(const MemberAnnounceMsg& coordinator) const;
  /// The coordinator admitted this participant as this member.
  bool confirmed() const;
  /// Why the coordinator refused this participant as this member ("" when it did not).
  std::string refusal() const;

  MemberSessionConfig config_;
  FrameInbox inbox_;
  Phase phase_ = Phase::joining;
  double created_s_ = 0.0;
  std::optional<MemberAnnounceMsg> coordinator_;
  std::deque<FrameGrantMsg> grants_;
  std::optional<RunControlMsg> control_;
  double control_s_ = 0.0;             // when the verdict arrived
  std::optional<double> interrupted_s_;
  bool coordinator_lost_ = false;
  std::string failure_;
  bool admitted_ = false;              // takes part in the barrier (late joiners: once named)
  bool owner_confirmed_ = false;       // the coordinator named this participant as the member
  bool stepping_ = false;              // a step was handed out and has not ended yet
  std::int64_t next_frame_ = 0;
  std::optional<FrameSamples> resumed_inputs_;  // for the first frame after resume()
  std::uint32_t epoch_ = 0;
  bool rolling_back_ = false;          // a rollback was handed out and has not ended yet
  std::int64_t waiting_frame_ = -1;    // the granted frame whose inputs are awaited ...
  double waiting_since_s_ = 0.0;       // ... since then
};

}  // namespace syndds::proto
