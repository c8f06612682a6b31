// The coordinator's admission rules (docs/protocol.md, "Admission"), rule by rule.
#include <gtest/gtest.h>

#include <cmath>

#include "protocol/admission.hpp"

using namespace syndds::proto;
using Claim = Admission::Claim;

namespace {

std::vector<std::string> refused_members(const Admission& a) {
  std::vector<std::string> out;
  for (const auto& entry : a.refused_list()) {
    std::string member, participant;
    EXPECT_TRUE(split_member_entry(entry, member, participant)) << entry;
    out.push_back(member + " " + participant);
  }
  return out;
}

}  // namespace

TEST(Admission, FirstClaimIsAdmittedAndRepeatsChangeNothing) {
  Admission a;
  EXPECT_EQ(a.on_claim("external/cy", "p1", false, 0.0), Claim::admitted);
  EXPECT_TRUE(a.take_changed());
  EXPECT_EQ(a.on_claim("external/cy", "p1", false, 0.5), Claim::repeated);
  EXPECT_FALSE(a.take_changed());
  EXPECT_EQ(a.owner("external/cy"), "p1");
  EXPECT_EQ(a.admitted_list(), std::vector<std::string>{"external/cy p1"});
  EXPECT_TRUE(a.take_intrusions().empty());
}

// Without restarts (abort, continue) a second claim of a member is refused at once, told in
// the refused list, and recorded once however often it repeats.
TEST(Admission, SecondClaimantIsRefusedAtOnceWithoutRestarts) {
  Admission a;
  a.on_claim("external/cy", "p1", false, 0.0);
  a.take_changed();
  EXPECT_EQ(a.on_claim("external/cy", "p2", false, 1.0), Claim::refused);
  EXPECT_TRUE(a.take_changed());
  EXPECT_EQ(refused_members(a), std::vector<std::string>{"external/cy p2"});
  EXPECT_EQ(a.on_claim("external/cy", "p2", false, 1.5), Claim::refused);
  EXPECT_FALSE(a.take_changed());
  const auto intrusions = a.take_intrusions();
  ASSERT_EQ(intrusions.size(), 1u);
  EXPECT_EQ(intrusions[0].member, "external/cy");
  EXPECT_EQ(intrusions[0].participant, "p2");
  EXPECT_NE(intrusions[0].what.find("participant p1 is external/cy"), std::string::npos)
      << intrusions[0].what;
  EXPECT_EQ(a.owner("external/cy"), "p1");  // the owner is unchanged
}

// A done (or any protocol message) counts only from the owner; anybody else's is an intrusion
// and refuses its writer, so that it is told too.
TEST(Admission, MessagesCountOnlyFromTheOwner) {
  Admission a;
  a.on_claim("external/cy", "p1", false, 0.0);
  EXPECT_TRUE(a.accept("external/cy", "p1", "frame_done"));
  EXPECT_FALSE(a.accept("external/cy", "p2", "frame_done"));
  EXPECT_FALSE(a.accept("vehicle/x", "p3", "frame_done"));  // nobody is vehicle/x
  const auto intrusions = a.take_intrusions();
  ASSERT_EQ(intrusions.size(), 2u);
  EXPECT_EQ(intrusions[0].what, "wrote a frame_done: participant p1 is external/cy");
  EXPECT_EQ(intrusions[1].what, "wrote a frame_done: no participant is vehicle/x yet");
  EXPECT_EQ(refused_members(a), (std::vector<std::string>{"external/cy p2", "vehicle/x p3"}));
  // Refused as that member: its later claim is refused without a new intrusion.
  EXPECT_EQ(a.on_claim("vehicle/x", "p3", false, 1.0), Claim::refused);
  EXPECT_TRUE(a.take_intrusions().empty());
}

// Under recover a second claim is held: a restart may announce itself before its old
// process's loss is seen. Awaited (the loss was seen), it replaces the old participant, whose
// late messages are dropped quietly; not awaited within the hold, it is refused.
TEST(Admission, UnderRecoverASecondClaimIsHeldThenTakenOrRefused) {
  Admission a({.restarts = true, .claim_hold_s = 12.0});
  a.on_claim("vehicle/a", "old", false, 0.0);
  a.take_changed();
  EXPECT_EQ(a.on_claim("vehicle/a", "new", false, 5.0), Claim::held);
  EXPECT_FALSE(a.take_changed());
  EXPECT_EQ(a.held("vehicle/a"), std::vector<std::string>{"new"});
  EXPECT_DOUBLE_EQ(a.next_deadline_s(), 17.0);
  EXPECT_EQ(a.on_claim("vehicle/a", "new", true, 6.0), Claim::admitted);
  EXPECT_TRUE(a.take_changed());
  EXPECT_EQ(a.owner("vehicle/a"), "new");
  EXPECT_TRUE(a.held("vehicle/a").empty());
  EXPECT_FALSE(a.accept("vehicle/a", "old", "frame_done"));
  EXPECT_TRUE(a.take_intrusions().empty());  // the old process, not an intruder
  EXPECT_TRUE(a.refused_list().empty());

  EXPECT_EQ(a.on_claim("vehicle/a", "copy", false, 20.0), Claim::held);
  a.poll(31.9);
  EXPECT_TRUE(a.refused_list().empty());
  a.poll(32.0);
  EXPECT_EQ(refused_members(a), std::vector<std::string>{"vehicle/a copy"});
  EXPECT_TRUE(a.take_changed());
  EXPECT_EQ(a.take_intrusions().size(), 1u);
  EXPECT_TRUE(std::isinf(a.next_deadline_s()));
}

TEST(Admission, AHeldClaimantThatLeavesIsForgotten) {
  Admission a({.restarts = true, .claim_hold_s = 12.0});
  a.on_claim("vehicle/a", "old", false, 0.0);
  a.on_claim("vehicle/a", "copy", false, 1.0);
  a.forget("copy");
  a.poll(100.0);
  EXPECT_TRUE(a.refused_list().empty());
  EXPECT_TRUE(a.take_intrusions().empty());
}

TEST(Admission, RefusedForOtherReasonsIsToldWithTheReason) {
  Admission a;
  a.refuse("sensor/a", "p9", "loaded a different scenario");
  EXPECT_EQ(a.refused_list(), std::vector<std::string>{"sensor/a p9 loaded a different scenario"});
  std::string member, participant, why;
  ASSERT_TRUE(split_member_entry(a.refused_list()[0], member, participant, &why));
  EXPECT_EQ(member, "sensor/a");
  EXPECT_EQ(participant, "p9");
  EXPECT_EQ(why, "loaded a different scenario");
  EXPECT_FALSE(split_member_entry("lonely", member, participant));
  EXPECT_FALSE(split_member_entry("m ", member, participant));
}
