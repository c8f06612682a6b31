#include <gtest/gtest.h>

#include "protocol/member_session.hpp"

using namespace syndds::proto;
using Kind = MemberSession::Action::Kind;
using Outcome = MemberSession::Outcome;

namespace {

constexpr std::uint64_t kFingerprint = 42;

MemberSessionConfig config(const std::string& member = "recorder") {
  MemberSessionConfig c;
  c.member_id = member;
  c.run_id = std::string("r");  // not = "r": GCC 12 -Wrestrict false positive (PR 105329)
  c.transport = "DDS domain 7";
  c.config_fingerprint = kFingerprint;
  c.heartbeat_s = 0.01;
  c.join_timeout_s = 5.0;
  c.input_timeout_s = 3.0;
  c.final_timeout_s = 4.0;
  c.interrupt_grace_s = 2.0;
  c.participant_guid = "0a.0b";
  return c;
}

std::vector<Subscription> states() { return {{Topic::vehicle_state, ""}}; }

MemberAnnounceMsg coordinator(std::vector<std::string> expected = {"recorder", "sensor/a"}) {
  MemberAnnounceMsg a;
  a.member_id = "coordinator";
  a.kind = MemberKind::coordinator;
  a.run_id = std::string("r");
  a.participant_guid = "01.02";
  a.host = "h1";
  a.pid = 10;
  a.config_fingerprint = kFingerprint;
  a.expected_members = std::move(expected);
  for (const auto& m : a.expected_members) a.admitted.push_back(m + " 0a.0b");
  return a;
}

VehicleStateMsg state(std::int64_t frame, const std::string& v = "a") {
  VehicleStateMsg s;
  s.vehicle_id = v;
  s.source = "vehicle/" + v;
  s.frame = frame;
  return s;
}

TopicCount announced(const std::string& v = "a") {
  return {Topic::vehicle_state, v, "vehicle/" + v, 1};
}

FrameGrantMsg grant(std::int64_t frame, Manifest manifest = {},
                    std::vector<std::string> joiners = {}) {
  FrameGrantMsg g;
  g.frame = frame;
  g.sim_time_s = 0.01 * static_cast<double>(frame);
  g.manifest = std::move(manifest);
  g.joiners = std::move(joiners);
  return g;
}

RunControlMsg control(RunStatus status, std::int64_t final_frame, Manifest manifest = {},
                      const std::string& reason = "") {
  RunControlMsg c;
  c.status = status;
  c.final_frame = final_frame;
  c.final_manifest = std::move(manifest);
  c.reason = reason;
  return c;
}

// A session that joined a run (the coordinator announced, checks passed).
MemberSession joined(MemberSessionConfig c = config()) {
  MemberSession s(states(), std::move(c), 0.0);
  EXPECT_EQ(s.on_coordinator(coordinator(), 0.1), "");
  EXPECT_EQ(s.poll(0.1).kind, Kind::joined);
  return s;
}

// Steps the granted frame `frame` and reports it done.
void step(MemberSession& s, std::int64_t frame, double t) {
  auto a = s.poll(t);
  ASSERT_EQ(a.kind, Kind::step);
  ASSERT_EQ(a.context.frame, frame);
  s.on_stepped(frame, "", t);
}

}  // namespace

TEST(MemberSession, WaitsForTheCoordinatorThenJoins) {
  MemberSession s(states(), config(), 0.0);
  auto w = s.poll(0.0);
  EXPECT_EQ(w.kind, Kind::wait);
  EXPECT_DOUBLE_EQ(w.wake_at_s, 5.0);
  EXPECT_EQ(s.on_coordinator(coordinator(), 1.0), "");
  EXPECT_EQ(s.poll(1.0).kind, Kind::joined);
  EXPECT_EQ(s.phase(), MemberSession::Phase::running);
  EXPECT_EQ(s.poll(1.0).kind, Kind::wait);  // joined is said once
}

TEST(MemberSession, NoCoordinatorWithinTheJoinTimeoutFails) {
  MemberSession s(states(), config(), 0.0);
  EXPECT_EQ(s.poll(4.9).kind, Kind::wait);
  auto a = s.poll(5.0);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::failed);
  EXPECT_EQ(a.control.status, RunStatus::aborted);
  EXPECT_EQ(a.control.reason, "no coordinator for run 'r' on DDS domain 7 within 5 s");
  EXPECT_FALSE(a.confirm);
  EXPECT_EQ(s.poll(6.0).kind, Kind::wait);  // finish is said once
}

TEST(MemberSession, CoordinatorThatDoesNotExpectThisMemberIsRefused) {
  MemberSession s(states(), config(), 0.0);
  s.on_coordinator(coordinator({"vehicle/a"}), 0.1);
  auto a = s.poll(0.1);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::failed);
  EXPECT_EQ(a.error, "the coordinator of run 'r' does not expect member recorder");
}

TEST(MemberSession, ScenarioMismatchNamesBothFingerprints) {
  MemberSession s(states(), config(), 0.0);
  auto c = coordinator();
  c.config_fingerprint = 7;
  s.on_coordinator(c, 0.1);
  auto a = s.poll(0.1);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::failed);
  EXPECT_NE(a.error.find("scenario mismatch"), std::string::npos) << a.error;
  EXPECT_NE(a.error.find("fingerprint 0000000000000007, mine 000000000000002a"),
            std::string::npos)
      << a.error;
  EXPECT_NE(a.error.find("--format files"), std::string::npos) << a.error;  // how to find why
}

TEST(MemberSession, ProtocolVersionMismatchFails) {
  MemberSession s(states(), config(), 0.0);
  auto c = coordinator();
  c.protocol_version = kProtocolVersion + 1;
  s.on_coordinator(c, 0.1);
  auto a = s.poll(0.1);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_NE(a.error.find("protocol version mismatch"), std::string::npos) << a.error;
}

TEST(MemberSession, ASecondCoordinatorIsAFailure) {
  auto s = joined();
  auto other = coordinator();
  other.participant_guid = "09.09";
  other.host = "h2";
  EXPECT_EQ(s.on_coordinator(coordinator(), 0.2), "");  // the same one again: harmless
  EXPECT_NE(s.on_coordinator(other, 0.2), "");
  auto a = s.poll(0.2);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::failed);
  EXPECT_NE(a.error.find("a second coordinator (pid 10 on h2)"), std::string::npos) << a.error;
}

TEST(MemberSession, InterruptBeforeTheCoordinatorEndsAtOnce) {
  MemberSession s(states(), config(), 0.0);
  s.on_interrupt(0.5);
  auto a = s.poll(0.5);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::interrupted);
  EXPECT_EQ(a.control.reason, "interrupted");
  EXPECT_TRUE(a.error.empty());  // an interrupt is not a failure to report
}

// The data barrier: grant k runs only when every announced sample stamped k-1 that the member
// subscribes to is in the inbox; the step gets exactly those samples.
TEST(MemberSession, FrameStartsOnlyWhenItsAnnouncedInputsArrived) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.on_grant(grant(1, {announced("a"), announced("b")}), 0.3);
  EXPECT_FALSE(s.add(state(0, "a")));  // kept; the frame still waits for b: no wake-up
  EXPECT_EQ(s.poll(0.3).kind, Kind::wait);
  EXPECT_TRUE(s.add(state(0, "b")));  // completes frame 1's inputs: wake the member
  auto a = s.poll(0.4);
  ASSERT_EQ(a.kind, Kind::step);
  EXPECT_EQ(a.context.frame, 1);
  EXPECT_DOUBLE_EQ(a.context.sim_time_s, 0.01);
  EXPECT_DOUBLE_EQ(a.context.heartbeat_s, 0.01);
  ASSERT_EQ(a.inputs.vehicle_states.size(), 2u);
  EXPECT_EQ(a.inputs.vehicle_states[0].vehicle_id, "a");
  EXPECT_EQ(a.inputs.vehicle_states[1].vehicle_id, "b");
}

// A member that receives many samples per frame (a vehicle on soft soil: every neighbour's
// deformation) is woken once per frame, not once per sample: a sample says "act" only when it
// completes the inputs of the frame granted next; before the grant, the grant itself wakes.
TEST(MemberSession, OnlyTheSampleThatCompletesAGrantedFrameWakesTheMember) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  EXPECT_FALSE(s.add(state(0, "a")));  // before grant 1
  EXPECT_FALSE(s.add(state(0, "b")));
  s.on_grant(grant(1, {announced("a"), announced("b"), announced("c")}), 0.3);
  EXPECT_EQ(s.poll(0.3).kind, Kind::wait);
  EXPECT_FALSE(s.add(state(0, "x")));  // kept (all keys are subscribed), but not announced
  EXPECT_TRUE(s.add(state(0, "c")));   // the last announced input of frame 1
  ASSERT_EQ(s.poll(0.3).kind, Kind::step);
  EXPECT_FALSE(s.add(state(1, "a")));  // while frame 1 steps, no grant 2
  s.on_stepped(1, "", 0.35);
  EXPECT_FALSE(s.add(state(1, "b")));  // no grant 2 yet
  // Anything but a plain running wait is left to poll(): the verdict, a failure.
  s.on_control(RunControlMsg{}, 0.4);
  EXPECT_TRUE(s.add(state(1, "c")));
}

TEST(MemberSession, NoNewStepWhileOneRuns) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  s.on_grant(grant(1), 0.2);
  ASSERT_EQ(s.poll(0.2).kind, Kind::step);
  EXPECT_EQ(s.poll(0.2).kind, Kind::wait);  // frame 0 has not ended
  s.on_stepped(0, "", 0.3);
  auto a = s.poll(0.3);
  ASSERT_EQ(a.kind, Kind::step);
  EXPECT_EQ(a.context.frame, 1);
}

TEST(MemberSession, SkipDataBarrierStartsWithWhateverArrived) {
  auto c = config();
  c.skip_data_barrier = true;
  auto s = joined(c);
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.on_grant(grant(1, {announced()}), 0.3);
  auto a = s.poll(0.3);
  ASSERT_EQ(a.kind, Kind::step);
  EXPECT_TRUE(a.inputs.vehicle_states.empty());
}

TEST(MemberSession, MissingInputsFailAfterTheInputTimeoutNamingThem) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.on_grant(grant(1, {announced()}), 1.0);
  auto w = s.poll(1.0);
  ASSERT_EQ(w.kind, Kind::wait);
  EXPECT_DOUBLE_EQ(w.wake_at_s, 4.0);
  EXPECT_EQ(s.poll(3.9).kind, Kind::wait);
  auto a = s.poll(4.0);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::failed);
  EXPECT_EQ(a.error,
            "frame 1: announced inputs missing after 3 s: vehicle_state key=a from vehicle/a: "
            "have 0 of 1");
  EXPECT_EQ(a.error_frame, 1);
}

TEST(MemberSession, DuplicateGrantsAreIgnoredAndASkippedFrameIsAProtocolError) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.on_grant(grant(0), 0.3);  // replayed
  EXPECT_EQ(s.poll(0.3).kind, Kind::wait);
  s.on_grant(grant(2), 0.4);
  auto a = s.poll(0.4);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.error, "protocol error: granted frame 2 while frame 1 was expected");
}

TEST(MemberSession, AFailedStepEndsTheRunAndIsReported) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  ASSERT_EQ(s.poll(0.2).kind, Kind::step);
  s.on_stepped(0, "boom", 0.3);
  auto a = s.poll(0.3);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::failed);
  EXPECT_EQ(a.error, "frame 0: boom");
  EXPECT_EQ(a.error_frame, 1);
  EXPECT_EQ(a.control.status, RunStatus::aborted);
  EXPECT_FALSE(a.confirm);
}

TEST(MemberSession, AFailureOfTheTransportEndsTheRun) {
  auto s = joined();
  s.on_failure("received a malformed frame_grant sample: x", 0.2);
  s.on_failure("second reason", 0.2);  // the first one wins
  auto a = s.poll(0.2);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.error, "received a malformed frame_grant sample: x");
}

TEST(MemberSession, LostCoordinatorEndsTheRun) {
  auto s = joined();
  s.on_coordinator_lost(0.5);
  auto a = s.poll(0.5);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::failed);
  EXPECT_EQ(a.control.reason,
            "the coordinator was lost (its process exited or stopped answering)");
}

// A late joiner ignores grants until one names it, then starts with the next frame.
TEST(MemberSession, LateJoinerStartsAfterTheGrantNamingIt) {
  auto c = config("sensor/a");
  c.late_join = true;
  auto s = joined(c);
  EXPECT_FALSE(s.admitted());
  for (std::int64_t f = 0; f < 4; ++f) s.on_grant(grant(f), 0.2);  // replayed, not for it
  EXPECT_EQ(s.poll(0.2).kind, Kind::wait);
  EXPECT_FALSE(s.admitted());
  s.on_grant(grant(4, {}, {"sensor/a"}), 0.3);
  EXPECT_EQ(s.poll(0.3).kind, Kind::wait);
  EXPECT_TRUE(s.admitted());
  EXPECT_EQ(s.next_frame(), 5);
  EXPECT_FALSE(s.add(state(4)));  // kept; nothing to do before grant 5
  s.on_grant(grant(5, {announced()}), 0.4);
  auto a = s.poll(0.4);
  ASSERT_EQ(a.kind, Kind::step);
  EXPECT_EQ(a.context.frame, 5);
  ASSERT_EQ(a.inputs.vehicle_states.size(), 1u);
  EXPECT_EQ(a.inputs.vehicle_states[0].frame, 4);
}

// Joiners and departed members reach the agent through its frame context.
TEST(MemberSession, GrantNewsReachesTheFrameContext) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  auto g = grant(1, {}, {"sensor/a"});
  g.departed = {"controller/b"};
  s.on_grant(g, 0.3);
  auto a = s.poll(0.3);
  ASSERT_EQ(a.kind, Kind::step);
  EXPECT_EQ(a.context.joiners, std::vector<std::string>{"sensor/a"});
  EXPECT_EQ(a.context.departed, std::vector<std::string>{"controller/b"});
}

// After RunControl: the final frame's announced samples are gathered and handed to finish().
TEST(MemberSession, CompletedRunHandsOverTheFinalFrame) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.on_control(control(RunStatus::completed, 0, {announced()}), 0.3);
  EXPECT_EQ(s.poll(0.3).kind, Kind::wait);
  s.add(state(0));
  auto a = s.poll(0.4);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::completed);
  EXPECT_TRUE(a.confirm);
  EXPECT_TRUE(a.error.empty());
  ASSERT_EQ(a.inputs.vehicle_states.size(), 1u);
  EXPECT_EQ(a.inputs.vehicle_states[0].frame, 0);
}

// The verdict wins over a grant still waiting for its inputs.
TEST(MemberSession, RunControlWinsOverAWaitingGrant) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.add(state(0));
  s.on_grant(grant(1, {announced(), announced("b")}), 0.3);
  EXPECT_EQ(s.poll(0.3).kind, Kind::wait);
  s.on_control(control(RunStatus::aborted, 0, {announced()}, "member vehicle/b lost"), 0.4);
  auto a = s.poll(0.4);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::aborted);
  EXPECT_EQ(a.control.reason, "member vehicle/b lost");
  ASSERT_EQ(a.inputs.vehicle_states.size(), 1u);
}

// A frame already consumed (the member stepped the next one) is not handed out twice.
TEST(MemberSession, FinalFrameAlreadyConsumedIsNotGatheredAgain) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.add(state(0));
  s.on_grant(grant(1, {announced()}), 0.3);
  step(s, 1, 0.3);
  s.on_control(control(RunStatus::aborted, 0, {announced()}, "frame 1 missed"), 0.4);
  auto a = s.poll(0.4);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_TRUE(a.inputs.empty());
  EXPECT_EQ(a.outcome, Outcome::aborted);
}

// Never a partial frame: the member ends without it, says what was missing and fails.
TEST(MemberSession, IncompleteFinalFrameIsNotUsed) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.on_control(control(RunStatus::completed, 0, {announced(), announced("b")}), 1.0);
  s.add(state(0));
  EXPECT_EQ(s.poll(4.9).kind, Kind::wait);
  auto a = s.poll(5.0);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::failed);
  EXPECT_TRUE(a.inputs.empty());
  EXPECT_TRUE(a.confirm);
  EXPECT_EQ(a.control.status, RunStatus::aborted);
  EXPECT_EQ(a.control.reason,
            "final frame 0 incomplete at recorder: vehicle_state key=b from vehicle/b: have 0 of 1");
}

// Interrupted (the coordinator got the same signal): no new frame, a short wait for the
// coordinator's verdict, then the last complete frame is still handed over.
TEST(MemberSession, InterruptWaitsForTheVerdictAndKeepsTheLastCompleteFrame) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.add(state(0));
  s.on_grant(grant(1, {announced()}), 0.3);
  s.on_interrupt(0.3);
  auto w = s.poll(0.3);
  ASSERT_EQ(w.kind, Kind::wait);  // frame 1 does not start
  EXPECT_DOUBLE_EQ(w.wake_at_s, 2.3);
  s.on_control(control(RunStatus::aborted, 0, {announced()}, "interrupted"), 0.5);
  auto a = s.poll(0.5);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::interrupted);
  EXPECT_TRUE(a.confirm);
  ASSERT_EQ(a.inputs.vehicle_states.size(), 1u);
  EXPECT_EQ(a.inputs.vehicle_states[0].frame, 0);
}

TEST(MemberSession, InterruptWithoutAVerdictEndsAfterTheGrace) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.on_interrupt(1.0);
  EXPECT_EQ(s.poll(2.9).kind, Kind::wait);
  auto a = s.poll(3.0);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::interrupted);
  EXPECT_EQ(a.control.reason, "interrupted");
  EXPECT_FALSE(a.confirm);
  EXPECT_TRUE(a.error.empty());
}

// After an interrupt the final gathering is bounded by the grace, not the final timeout.
TEST(MemberSession, InterruptBoundsTheFinalGathering) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.on_control(control(RunStatus::aborted, 0, {announced()}, "interrupted"), 1.0);
  s.on_interrupt(1.0);
  auto w = s.poll(1.0);
  ASSERT_EQ(w.kind, Kind::wait);
  EXPECT_DOUBLE_EQ(w.wake_at_s, 3.0);
  auto a = s.poll(3.0);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::failed);
}

TEST(MemberSession, CompletedRunWinsOverALateInterrupt) {
  auto s = joined();
  s.on_grant(grant(0), 0.2);
  step(s, 0, 0.2);
  s.on_control(control(RunStatus::completed, 0), 0.3);
  s.on_interrupt(0.3);
  auto a = s.poll(0.3);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::completed);
}

// A member resumed from its checkpoint steps the first granted frame with its saved inputs at
// once (the grant announces none), then waits for announced samples as usual.
TEST(MemberSession, AResumedMemberStepsItsFirstFrameWithTheSavedInputs) {
  auto c = config();
  c.resume_frame = 9;
  MemberSession s(states(), c, 0.0);
  FrameSamples saved;
  saved.vehicle_states.push_back(state(9));
  s.resume(saved);
  EXPECT_EQ(s.next_frame(), 10);
  EXPECT_EQ(s.on_coordinator(coordinator(), 0.1), "");
  EXPECT_EQ(s.poll(0.1).kind, Kind::joined);
  s.on_grant(grant(10), 0.2);
  auto a = s.poll(0.2);
  ASSERT_EQ(a.kind, Kind::step);
  EXPECT_EQ(a.context.frame, 10);
  ASSERT_EQ(a.inputs.vehicle_states.size(), 1u);
  EXPECT_EQ(a.inputs.vehicle_states[0].frame, 9);
  s.on_stepped(10, "", 0.3);
  s.on_grant(grant(11, {announced()}), 0.3);
  EXPECT_EQ(s.poll(0.3).kind, Kind::wait);  // frame 10's state has not arrived
  s.add(state(10));
  step(s, 11, 0.4);
}

TEST(MemberSession, AResumedMemberRefusesAGrantOfAnotherFrame) {
  auto c = config();
  c.resume_frame = 9;
  MemberSession s(states(), c, 0.0);
  s.resume({});
  EXPECT_EQ(s.on_coordinator(coordinator(), 0.1), "");
  EXPECT_EQ(s.poll(0.1).kind, Kind::joined);
  s.on_grant(grant(12), 0.2);
  auto a = s.poll(0.2);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_NE(a.error.find("granted frame 12 while frame 10 was expected"), std::string::npos)
      << a.error;
}

// Admission: a member acts on grants only once the coordinator admitted this participant as
// it; until then grants wait (they are not errors, even when they skip frames).
TEST(MemberSession, GrantsWaitUntilTheCoordinatorAdmitsThisParticipant) {
  MemberSession s(states(), config(), 0.0);
  MemberAnnounceMsg c = coordinator();
  c.admitted = {"recorder 0c.0d"};  // another participant is the recorder, for now
  s.on_coordinator(c, 0.1);
  EXPECT_EQ(s.poll(0.1).kind, Kind::joined);
  s.on_grant(grant(0), 0.2);
  EXPECT_EQ(s.poll(0.2).kind, Kind::wait);
  s.on_grant(grant(1), 0.3);
  EXPECT_EQ(s.poll(0.3).kind, Kind::wait);
  s.on_coordinator(coordinator(), 0.4);  // the coordinator's newer word: this participant
  const auto a = s.poll(0.4);
  ASSERT_EQ(a.kind, Kind::step);
  EXPECT_EQ(a.context.frame, 0);
}

// A claimant the coordinator refused ends with its own outcome, reports no failure (it never
// took part: its done would be an intrusion) and confirms nothing.
TEST(MemberSession, ARefusedClaimantEndsRefusedWithTheCoordinatorsReason) {
  MemberSession s(states(), config(), 0.0);
  MemberAnnounceMsg c = coordinator();
  c.admitted = {"recorder 0c.0d"};
  s.on_coordinator(c, 0.1);
  EXPECT_EQ(s.poll(0.1).kind, Kind::joined);
  s.on_grant(grant(411), 0.2);  // a replayed grant of a run under way: not an error
  EXPECT_EQ(s.poll(0.2).kind, Kind::wait);
  c.refused = {"recorder 0a.0b participant 0c.0d is recorder"};
  s.on_coordinator(c, 0.3);
  const auto a = s.poll(0.3);
  ASSERT_EQ(a.kind, Kind::finish);
  EXPECT_EQ(a.outcome, Outcome::refused);
  EXPECT_TRUE(a.error.empty());
  EXPECT_FALSE(a.confirm);
  EXPECT_EQ(a.control.reason,
            "refused by the coordinator as recorder: participant 0c.0d is recorder");
}

// A grant's intrusions reach the agents in the frame's context (the recorder writes them).
TEST(MemberSession, IntrusionsReachTheFrameContext) {
  MemberSession s = joined();
  FrameGrantMsg g = grant(0);
  g.intrusions = {"external/cy 0e.0f wrote a frame_done: participant 0c.0d is external/cy"};
  s.on_grant(g, 0.2);
  const auto a = s.poll(0.2);
  ASSERT_EQ(a.kind, Kind::step);
  EXPECT_EQ(a.context.intrusions, g.intrusions);
}
