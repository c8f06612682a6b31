#include <gtest/gtest.h>

#include "protocol/barrier.hpp"

using namespace syndds::proto;
using Kind = Barrier::Action::Kind;

namespace {

BarrierConfig config(std::int64_t final_frame = 3) {
  BarrierConfig c;
  c.members = {"vehicle/a", "controller/a", "recorder"};
  c.final_frame = final_frame;
  c.heartbeat_s = 0.01;
  c.join_timeout_s = 5.0;
  c.frame_timeout_s = 2.0;
  return c;
}

FrameDoneMsg done(const std::string& member, std::int64_t frame, Manifest published = {}) {
  FrameDoneMsg d;
  d.member_id = member;
  d.frame = frame;
  d.published = std::move(published);
  return d;
}

void join_all(Barrier& b, double t) {
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) EXPECT_EQ(b.on_join(m, t), "");
}

// Every member joins and completes frame 0 at t = 0; true once frame 1 is granted.
bool run_to_frame_one(Barrier& b) {
  join_all(b, 0.0);
  b.poll(0.0);
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 0), 0.0);
  return b.poll(0.0).kind == Kind::grant;
}

}  // namespace

TEST(Barrier, GrantsFrameZeroOnlyWhenEveryMemberJoined) {
  Barrier b(config(), 0.0);
  EXPECT_EQ(b.poll(0.1).kind, Kind::wait);
  b.on_join("vehicle/a", 0.1);
  b.on_join("recorder", 0.1);
  EXPECT_EQ(b.poll(0.2).kind, Kind::wait);
  b.on_join("controller/a", 0.3);
  auto a = b.poll(0.3);
  ASSERT_EQ(a.kind, Kind::grant);
  EXPECT_EQ(a.grant.frame, 0);
  EXPECT_TRUE(a.grant.manifest.empty());
  EXPECT_EQ(b.poll(0.3).kind, Kind::wait);  // granted once
}

TEST(Barrier, JoinTimeoutNamesTheMissingMembers) {
  Barrier b(config(), 0.0);
  b.on_join("vehicle/a", 0.1);
  auto w = b.poll(1.0);
  EXPECT_EQ(w.kind, Kind::wait);
  EXPECT_DOUBLE_EQ(w.wake_at_s, 5.0);
  auto a = b.poll(5.0);
  ASSERT_EQ(a.kind, Kind::abort);
  EXPECT_NE(a.control.reason.find("join timeout"), std::string::npos);
  EXPECT_NE(a.control.reason.find("controller/a, recorder"), std::string::npos) << a.control.reason;
  EXPECT_EQ(a.control.reason.find("vehicle/a"), std::string::npos);
}

TEST(Barrier, UnknownMemberIsIgnoredWithAWarning) {
  Barrier b(config(), 0.0);
  EXPECT_NE(b.on_join("vehicle/zzz", 0.0).find("not a member"), std::string::npos);
  EXPECT_EQ(b.missing_members().size(), 3u);
}

TEST(Barrier, NextFrameWaitsForEveryDoneAndCarriesTheManifest) {
  Barrier b(config(), 0.0);
  join_all(b, 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  const TopicCount state{Topic::vehicle_state, "a", "vehicle/a", 1};
  b.on_done(done("vehicle/a", 0, {state}), 0.01);
  b.on_done(done("controller/a", 0), 0.01);
  EXPECT_EQ(b.poll(0.02).kind, Kind::wait);
  EXPECT_EQ(b.pending_members(), std::vector<std::string>{"recorder"});
  b.on_done(done("recorder", 0), 0.03);
  auto a = b.poll(0.03);
  ASSERT_EQ(a.kind, Kind::grant);
  EXPECT_EQ(a.grant.frame, 1);
  EXPECT_DOUBLE_EQ(a.grant.sim_time_s, 0.01);
  ASSERT_EQ(a.grant.manifest.size(), 1u);
  EXPECT_EQ(a.grant.manifest[0], state);
}

TEST(Barrier, DoneForAnotherFrameDoesNotCount) {
  Barrier b(config(), 0.0);
  join_all(b, 0.0);
  b.poll(0.0);
  EXPECT_NE(b.on_done(done("vehicle/a", 5), 0.0).find("frame 0 is current"), std::string::npos);
  EXPECT_EQ(b.pending_members().size(), 3u);
}

TEST(Barrier, FrameDeadlineNamesTheSlowMembers) {
  Barrier b(config(), 0.0);
  join_all(b, 0.0);
  b.poll(0.0);
  b.on_done(done("vehicle/a", 0), 0.1);
  b.on_done(done("recorder", 0), 0.1);
  EXPECT_EQ(b.poll(1.9).kind, Kind::wait);
  auto a = b.poll(2.0);
  ASSERT_EQ(a.kind, Kind::abort);
  EXPECT_NE(a.control.reason.find("frame 0 missed"), std::string::npos) << a.control.reason;
  EXPECT_NE(a.control.reason.find("controller/a"), std::string::npos) << a.control.reason;
  EXPECT_EQ(a.control.reason.find("recorder"), std::string::npos) << a.control.reason;
}

TEST(Barrier, LostMemberAbortsByDefault) {
  Barrier b(config(), 0.0);
  ASSERT_TRUE(run_to_frame_one(b));
  b.on_member_lost("vehicle/a", "liveliness lost", 0.5);
  // Other losses may follow within kLossGatherS (a partition): nothing is granted meanwhile.
  EXPECT_EQ(b.poll(0.5).kind, Kind::wait);
  auto a = b.poll(0.5 + Barrier::kLossGatherS);
  ASSERT_EQ(a.kind, Kind::abort);
  EXPECT_EQ(a.control.reason, "member vehicle/a lost: liveliness lost");
  EXPECT_EQ(a.control.final_frame, 0);  // frame 0 was the last complete frame
  EXPECT_EQ(a.control.stats.frames, 1u);
}

// A partition or a lost host takes several members within moments of each other: the abort
// names all of them (before, only the first). A member that then fails for want of their data,
// or an interrupt, does not take the loss's place as the reason.
TEST(Barrier, LossesWithinTheGatheringTimeAreNamedTogether) {
  Barrier b(config(), 0.0);
  ASSERT_TRUE(run_to_frame_one(b));
  b.on_member_lost("vehicle/a", "liveliness lost", 1.0);
  b.on_member_lost("controller/a", "liveliness lost", 1.4);
  FrameDoneMsg failed = done("recorder", 1);
  failed.error = "announced data missing";
  b.on_done(failed, 1.5);
  b.on_interrupt("interrupted", 1.6);
  EXPECT_EQ(b.poll(1.9).kind, Kind::wait);
  auto a = b.poll(1.0 + Barrier::kLossGatherS);
  ASSERT_EQ(a.kind, Kind::abort);
  EXPECT_EQ(a.control.reason, "members vehicle/a, controller/a lost: liveliness lost");
}

TEST(Barrier, AbortAfterACompleteFrameAnnouncesItsSamples) {
  Barrier b(config(), 0.0);
  join_all(b, 0.0);
  b.poll(0.0);
  const TopicCount state{Topic::vehicle_state, "a", "vehicle/a", 1};
  b.on_done(done("vehicle/a", 0, {state}), 0.0);
  b.on_done(done("controller/a", 0), 0.0);
  b.on_done(done("recorder", 0), 0.0);
  b.on_interrupt("interrupted", 0.0);
  auto a = b.poll(0.0);
  ASSERT_EQ(a.kind, Kind::abort);
  EXPECT_EQ(a.control.final_frame, 0);
  ASSERT_EQ(a.control.final_manifest.size(), 1u);
}

TEST(Barrier, ContinuePolicyDropsTheLostMember) {
  auto c = config();
  c.on_member_loss = LossPolicy::continue_run;
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  b.poll(0.0);
  b.on_done(done("vehicle/a", 0), 0.0);
  b.on_done(done("recorder", 0), 0.0);
  b.on_member_lost("controller/a", "process exited", 0.1);
  auto a = b.poll(0.1);
  ASSERT_EQ(a.kind, Kind::grant);
  EXPECT_EQ(a.grant.frame, 1);
  const auto stats = b.stats(0.1);
  bool seen = false;
  for (const auto& m : stats.members) {
    if (m.member_id == "controller/a") {
      EXPECT_TRUE(m.lost);
      seen = true;
    }
  }
  EXPECT_TRUE(seen);
}

TEST(Barrier, StopsAfterTheFinalFrameWithItsManifest) {
  Barrier b(config(1), 0.0);
  join_all(b, 0.0);
  b.poll(0.0);
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 0), 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  const TopicCount state{Topic::vehicle_state, "a", "vehicle/a", 1};
  b.on_done(done("vehicle/a", 1, {state}), 0.1);
  b.on_done(done("controller/a", 1), 0.1);
  b.on_done(done("recorder", 1), 0.1);
  auto a = b.poll(0.1);
  ASSERT_EQ(a.kind, Kind::stop);
  EXPECT_EQ(a.control.status, RunStatus::completed);
  EXPECT_EQ(a.control.final_frame, 1);
  ASSERT_EQ(a.control.final_manifest.size(), 1u);
  EXPECT_EQ(a.control.stats.frames, 2u);
  EXPECT_DOUBLE_EQ(a.control.stats.sim_time_s, 0.01);
  EXPECT_FALSE(b.all_finished());
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) {
    FrameDoneMsg f = done(m, 1);
    f.finished = true;
    b.on_done(f, 0.2);
  }
  EXPECT_TRUE(b.all_finished());
}

TEST(Barrier, RealtimePacesGrantsToTheWallClock) {
  auto c = config(10);
  c.realtime = true;
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  ASSERT_EQ(b.poll(1.0).kind, Kind::grant);  // frame 0 at t = 1.0
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 0), 1.001);
  auto w = b.poll(1.001);
  ASSERT_EQ(w.kind, Kind::wait);
  EXPECT_NEAR(w.wake_at_s, 1.01, 1e-12);
  EXPECT_EQ(b.poll(1.01).kind, Kind::grant);
}

TEST(Barrier, StatsCountResponseTimesAndTheSlowestMember) {
  Barrier b(config(5), 0.0);
  join_all(b, 0.0);
  b.poll(0.0);
  b.on_done(done("vehicle/a", 0), 0.001);
  b.on_done(done("controller/a", 0), 0.002);
  b.on_done(done("recorder", 0), 0.004);
  b.poll(0.004);
  const auto s = b.stats(0.004);
  for (const auto& m : s.members) {
    if (m.member_id == "recorder") {
      EXPECT_NEAR(m.mean_response_s, 0.004, 1e-12);
      EXPECT_EQ(m.slowest_count, 1u);
    } else {
      EXPECT_EQ(m.slowest_count, 0u);
    }
  }
}

// With the abort policy a member lost in the middle of a frame leaves that frame incomplete:
// its data will never come, so the frame must not be announced as final.
TEST(Barrier, FrameWithALostMemberIsNotComplete) {
  Barrier b(config(), 0.0);
  ASSERT_TRUE(run_to_frame_one(b));
  b.on_done(done("controller/a", 1, {{Topic::driver_command, "a", "controller/a", 1}}), 0.1);
  b.on_done(done("recorder", 1), 0.1);
  b.on_member_lost("vehicle/a", "killed", 0.2);
  auto a = b.poll(0.2 + Barrier::kLossGatherS);
  ASSERT_EQ(a.kind, Kind::abort);
  EXPECT_EQ(a.control.final_frame, 0);
  EXPECT_TRUE(a.control.final_manifest.empty());
}

// A late member is not waited for at the start; once it announces itself it is admitted at a
// frame boundary (named in that grant's joiners, a snapshot is due) and counted from the next
// frame on.
TEST(Barrier, LateMemberIsAdmittedAtAFrameBoundary) {
  auto c = config(100);
  c.late_members = {"sensor/a"};
  c.late_join_delay_s = 0.5;
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  auto g = b.poll(0.0);
  ASSERT_EQ(g.kind, Kind::grant);
  EXPECT_TRUE(g.grant.joiners.empty());
  auto finish_frame = [&](std::int64_t f, double t) {
    for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, f), t);
  };
  finish_frame(0, 0.1);
  ASSERT_EQ(b.poll(0.1).kind, Kind::grant);  // frame 1
  EXPECT_EQ(b.on_join("sensor/a", 0.2), "");
  finish_frame(1, 0.3);
  auto g2 = b.poll(0.3);  // frame 2: too early to admit (0.1 s after its announcement)
  ASSERT_EQ(g2.kind, Kind::grant);
  EXPECT_TRUE(g2.grant.joiners.empty());
  finish_frame(2, 0.8);
  auto g3 = b.poll(0.8);  // frame 3 names it: it takes part from frame 4 on
  ASSERT_EQ(g3.kind, Kind::grant);
  EXPECT_EQ(g3.grant.joiners, std::vector<std::string>{"sensor/a"});
  finish_frame(3, 0.9);
  ASSERT_EQ(b.poll(0.9).kind, Kind::grant);  // frame 4
  finish_frame(4, 1.0);
  EXPECT_EQ(b.poll(1.0).kind, Kind::wait);   // waits for the newcomer now
  EXPECT_EQ(b.pending_members(), std::vector<std::string>{"sensor/a"});
  b.on_done(done("sensor/a", 4), 1.0);
  EXPECT_EQ(b.poll(1.0).kind, Kind::grant);
}

TEST(Barrier, LateMemberPresentAtTheStartBeginsAtFrameOne) {
  auto c = config(10);
  c.late_members = {"sensor/a"};
  Barrier b(c, 0.0);
  b.on_join("sensor/a", 0.0);
  join_all(b, 0.0);
  auto g = b.poll(0.0);
  ASSERT_EQ(g.kind, Kind::grant);
  EXPECT_EQ(g.grant.joiners, std::vector<std::string>{"sensor/a"});
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 0), 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);  // frame 0 did not wait for it
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 1), 0.0);
  EXPECT_EQ(b.poll(0.0).kind, Kind::wait);   // frame 1 does
}

// An abort in the middle of frame k+1 still announces the samples of frame k (the last complete
// one): a member that has not consumed them yet (the recorder) can keep that frame.
TEST(Barrier, AbortMidFrameAnnouncesTheLastCompleteFrame) {
  Barrier b(config(), 0.0);
  join_all(b, 0.0);
  b.poll(0.0);
  const TopicCount state{Topic::vehicle_state, "a", "vehicle/a", 1};
  b.on_done(done("vehicle/a", 0, {state}), 0.0);
  b.on_done(done("controller/a", 0), 0.0);
  b.on_done(done("recorder", 0), 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);  // frame 1 under way
  b.on_done(done("vehicle/a", 1, {state}), 0.1);
  b.on_interrupt("interrupted", 0.1);
  auto a = b.poll(0.1);
  ASSERT_EQ(a.kind, Kind::abort);
  EXPECT_EQ(a.control.final_frame, 0);
  ASSERT_EQ(a.control.final_manifest.size(), 1u);
  EXPECT_EQ(a.control.final_manifest[0], state);
}

// Under the continue policy, a member that left is no longer announced in manifests.
TEST(Barrier, LeftMemberIsNotAnnounced) {
  auto c = config();
  c.on_member_loss = LossPolicy::continue_run;
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  b.poll(0.0);
  b.on_done(done("vehicle/a", 0, {{Topic::vehicle_state, "a", "vehicle/a", 1}}), 0.0);
  b.on_done(done("controller/a", 0), 0.0);
  b.on_member_lost("vehicle/a", "killed", 0.0);
  b.on_done(done("recorder", 0), 0.0);
  auto a = b.poll(0.0);
  ASSERT_EQ(a.kind, Kind::grant);
  EXPECT_TRUE(a.grant.manifest.empty());
}

// A member that fails says why; the run aborts with that reason.
TEST(Barrier, AMemberReportingAnErrorAbortsTheRunWithIt) {
  Barrier b(config(), 0.0);
  join_all(b, 0.0);
  b.poll(0.0);
  FrameDoneMsg d = done("vehicle/a", 0);
  d.error = "received a malformed driver_command sample: ...";
  b.on_done(d, 0.1);
  auto a = b.poll(0.1);
  ASSERT_EQ(a.kind, Kind::abort);
  EXPECT_EQ(a.control.reason, "member vehicle/a failed: received a malformed driver_command sample: ...");
}

// Under the continue policy every other member learns who left: the next grant names the member
// that left, and no later grant names it again.
TEST(Barrier, DepartedMemberIsNamedInTheNextGrantExactlyOnce) {
  auto c = config(10);
  c.on_member_loss = LossPolicy::continue_run;
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  b.on_done(done("vehicle/a", 0), 0.0);
  b.on_member_lost("controller/a", "process exited", 0.05);
  b.on_member_lost("controller/a", "process exited", 0.06);  // reported twice: still one entry
  b.on_done(done("recorder", 0), 0.1);
  auto g1 = b.poll(0.1);
  ASSERT_EQ(g1.kind, Kind::grant);
  EXPECT_EQ(g1.grant.departed, std::vector<std::string>{"controller/a"});
  b.on_done(done("vehicle/a", 1), 0.2);
  b.on_done(done("recorder", 1), 0.2);
  auto g2 = b.poll(0.2);
  ASSERT_EQ(g2.kind, Kind::grant);
  EXPECT_TRUE(g2.grant.departed.empty());
}

// Under the abort policy nobody departs: the run ends instead.
TEST(Barrier, AbortPolicyNamesNoDeparture) {
  Barrier b(config(10), 0.0);
  join_all(b, 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 0), 0.0);
  auto g = b.poll(0.0);
  ASSERT_EQ(g.kind, Kind::grant);
  EXPECT_TRUE(g.grant.departed.empty());
  b.on_member_lost("vehicle/a", "killed", 0.1);
  EXPECT_EQ(b.poll(0.1 + Barrier::kLossGatherS).kind, Kind::abort);
}

// A late joiner that never took part and goes away is not a departure.
TEST(Barrier, LateMemberThatNeverTookPartDoesNotDepart) {
  auto c = config(10);
  c.on_member_loss = LossPolicy::continue_run;
  c.late_members = {"sensor/a"};
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  EXPECT_EQ(b.on_join("sensor/a", 0.1), "");
  b.on_member_lost("sensor/a", "process exited", 0.2);
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 0), 0.3);
  auto g = b.poll(0.3);
  ASSERT_EQ(g.kind, Kind::grant);
  EXPECT_TRUE(g.grant.departed.empty());
}

// A late sensor started with a stale scenario is refused by name; the run goes on.
TEST(Barrier, LateMemberWithAnotherScenarioIsRefusedAndTheRunGoesOn) {
  auto c = config(10);
  c.late_members = {"sensor/a"};
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  const std::string w = b.on_config_mismatch("sensor/a", "loaded a different scenario", 0.1);
  EXPECT_NE(w.find("refusing member sensor/a"), std::string::npos) << w;
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 0), 0.2);
  auto g = b.poll(5.0);
  ASSERT_EQ(g.kind, Kind::grant);
  EXPECT_TRUE(g.grant.joiners.empty());
  EXPECT_EQ(b.phase(), Barrier::Phase::running);
}

// A member expected at the start with another scenario still aborts the run at join time.
TEST(Barrier, StartMemberWithAnotherScenarioAbortsAtJoinTime) {
  Barrier b(config(), 0.0);
  EXPECT_EQ(b.on_join("vehicle/a", 0.0), "");
  EXPECT_EQ(b.on_config_mismatch("recorder", "on h2 loaded a different scenario", 0.1), "");
  auto a = b.poll(0.1);
  ASSERT_EQ(a.kind, Kind::abort);
  EXPECT_EQ(a.control.reason, "member recorder on h2 loaded a different scenario");
}

// The error of a member that is not (a late joiner not admitted) or no longer (left under the
// continue policy) in the barrier does not abort the run.
TEST(Barrier, ErrorOfAMemberOutsideTheBarrierIsIgnored) {
  auto c = config(10);
  c.on_member_loss = LossPolicy::continue_run;
  c.late_members = {"sensor/a"};
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  b.on_member_lost("controller/a", "process exited", 0.0);
  FrameDoneMsg late = done("controller/a", 0);
  late.error = "frame 0: could not publish";
  EXPECT_NE(b.on_done(late, 0.1).find("controller/a"), std::string::npos);
  EXPECT_EQ(b.on_join("sensor/a", 0.1), "");
  FrameDoneMsg stale = done("sensor/a", 0);
  stale.error = "scenario mismatch";
  EXPECT_NE(b.on_done(stale, 0.1).find("sensor/a"), std::string::npos);
  b.on_done(done("vehicle/a", 0), 0.2);
  b.on_done(done("recorder", 0), 0.2);
  EXPECT_EQ(b.poll(0.2).kind, Kind::grant);
  EXPECT_EQ(b.phase(), Barrier::Phase::running);
}

// A member that fails after the run completed: the run stays completed, nobody counts it as
// lost, and the barrier names its failure after the end.
TEST(Barrier, FailureAfterACompletedRunIsNotALoss) {
  Barrier b(config(0), 0.0);
  join_all(b, 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 0), 0.0);
  auto s = b.poll(0.0);
  ASSERT_EQ(s.kind, Kind::stop);
  FrameDoneMsg f = done("recorder", 0);
  f.finished = true;
  f.error = "cannot write summary.json";
  b.on_done(f, 0.1);
  b.on_member_lost("recorder", "its DDS participant left", 0.2);
  b.on_done([] { auto d = done("vehicle/a", 0); d.finished = true; return d; }(), 0.1);
  b.on_member_lost("vehicle/a", "its DDS participant left", 0.2);  // after confirming: fine
  b.on_member_lost("controller/a", "liveliness lost", 0.3);        // gone without confirming
  EXPECT_TRUE(b.all_finished());
  EXPECT_EQ(b.phase(), Barrier::Phase::stopped);
  const auto failed = b.failed_after_end();
  ASSERT_EQ(failed.size(), 2u);
  EXPECT_EQ(failed.at("recorder"), "cannot write summary.json");
  EXPECT_NE(failed.at("controller/a").find("without confirming"), std::string::npos);
  for (const auto& m : b.stats(0.3).members) EXPECT_FALSE(m.lost) << m.member_id;
}

// Checkpoints (docs/checkpoints.md): members write the checkpoint of frame K before stepping
// K + 1 and say so in that done; the checkpoint is complete only when every member did.
TEST(Barrier, ACheckpointIsCompleteOnlyWhenEveryMemberReportedItsState) {
  auto c = config(6);
  c.checkpoint_every = 2;
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  for (std::int64_t f = 0; f <= 2; ++f) {
    ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
    for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, f), 0.0);
  }
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);  // frame 3: the members write the state of frame 2
  EXPECT_FALSE(b.take_checkpoint());          // nothing due before
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) {
    auto d = done(m, 3);
    d.checkpoint_bytes = std::string(m) == "recorder" ? 0 : 100;
    b.on_done(d, 0.0);
  }
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  auto r = b.take_checkpoint();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->frame, 2);
  EXPECT_EQ(r->members.size(), 2u);
  EXPECT_EQ(r->missing, std::vector<std::string>{"recorder"});
  EXPECT_FALSE(b.take_checkpoint());  // taken once

  // Frame 4 done, frame 5 granted: the checkpoint of frame 4, everyone this time.
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 4), 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) {
    auto d = done(m, 5);
    d.checkpoint_bytes = 7;
    b.on_done(d, 0.0);
  }
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  r = b.take_checkpoint();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->frame, 4);
  EXPECT_EQ(r->members.size(), 3u);
  EXPECT_TRUE(r->missing.empty());
}

TEST(Barrier, AResumedRunStartsAfterItsCheckpointWithoutAnnouncedInputs) {
  auto c = config(6);
  c.first_frame = 5;
  c.checkpoint_every = 4;
  Barrier b(c, 0.0);
  join_all(b, 0.0);
  auto a = b.poll(0.0);
  ASSERT_EQ(a.kind, Kind::grant);
  EXPECT_EQ(a.grant.frame, 5);
  EXPECT_DOUBLE_EQ(a.grant.sim_time_s, 0.05);
  EXPECT_TRUE(a.grant.manifest.empty());  // the members step it with their saved inputs
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 5), 0.0);
  ASSERT_EQ(b.poll(0.0).kind, Kind::grant);
  EXPECT_FALSE(b.take_checkpoint());  // the checkpoint of frame 4 is the one resumed from
  for (const auto* m : {"vehicle/a", "controller/a", "recorder"}) b.on_done(done(m, 6), 0.0);
  auto end = b.poll(0.0);
  ASSERT_EQ(end.kind, Kind::stop);
  EXPECT_EQ(end.control.final_frame, 6);
}
