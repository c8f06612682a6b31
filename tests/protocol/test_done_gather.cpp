// When a process with several members sends their dones (proto::DoneGather): together once
// every member taking part answered the grant, never later than the coordinator needs them.
#include <gtest/gtest.h>

#include "protocol/done_gather.hpp"

using namespace syndds::proto;

namespace {
FrameDoneMsg done_of(const std::string& member, std::int64_t frame, std::uint32_t epoch = 0) {
  FrameDoneMsg d;
  d.member_id = member;
  d.frame = frame;
  d.epoch = epoch;
  return d;
}
std::vector<std::string> names(const std::vector<FrameDoneMsg>& dones) {
  std::vector<std::string> out;
  for (const auto& d : dones) out.push_back(d.member_id + "@" + std::to_string(d.frame));
  return out;
}
using Names = std::vector<std::string>;
}  // namespace

// Once every member answered the grant, its dones go out in one batch.
TEST(DoneGather, SendsOnceEveryMemberTakingPartAnswered) {
  DoneGather g;
  // Frame 0: each member takes part from its first done, so nothing waits for a member that
  // has not answered yet.
  EXPECT_EQ(names(g.add(done_of("a", 0), 0.0)), Names{"a@0"});
  EXPECT_EQ(names(g.add(done_of("b", 0), 0.0)), Names{"b@0"});
  EXPECT_EQ(names(g.add(done_of("c", 0), 0.0)), Names{"c@0"});
  // From frame 1 on, the three go together.
  EXPECT_TRUE(g.add(done_of("b", 1), 0.1).empty());
  EXPECT_TRUE(g.add(done_of("a", 1), 0.1).empty());
  EXPECT_EQ(g.held(), 2u);
  EXPECT_EQ(names(g.add(done_of("c", 1), 0.1)), (Names{"b@1", "a@1", "c@1"}));
  EXPECT_EQ(g.held(), 0u);
  EXPECT_FALSE(g.deadline().has_value());
}

// A member that answered a grant already does not hold the others back when one of them comes
// in late for the same grant (here b's first done after a's was sent alone).
TEST(DoneGather, AMemberThatAnsweredAlreadyCountsAsAnswered) {
  DoneGather g;
  EXPECT_EQ(names(g.add(done_of("a", 0), 0.0)), Names{"a@0"});
  EXPECT_EQ(names(g.add(done_of("b", 0), 0.0)), Names{"b@0"});
  EXPECT_TRUE(g.add(done_of("a", 1), 0.0).empty());
  EXPECT_EQ(names(g.add(done_of("b", 1), 0.0)), (Names{"a@1", "b@1"}));
}

// A member whose run ended answers nothing more: what waited for it goes out.
TEST(DoneGather, ALeavingMemberReleasesTheOthers) {
  DoneGather g;
  g.add(done_of("a", 0), 0.0);
  g.add(done_of("b", 0), 0.0);
  EXPECT_TRUE(g.add(done_of("a", 1), 0.0).empty());
  EXPECT_EQ(names(g.leave("b")), Names{"a@1"});
  EXPECT_EQ(names(g.add(done_of("a", 2), 0.0)), Names{"a@2"});  // alone from now on
}

// A done of another grant (the next epoch after a rollback, or a later frame) sends what was
// held first: those answer an older grant, and nothing more will join them.
TEST(DoneGather, ADoneOfAnotherGrantSendsTheHeldOnesFirst) {
  DoneGather g;
  g.add(done_of("a", 0), 0.0);
  g.add(done_of("b", 0), 0.0);
  EXPECT_TRUE(g.add(done_of("a", 5), 0.0).empty());
  EXPECT_EQ(names(g.add(done_of("b", 3, 1), 0.0)), Names{"a@5"});  // rollback: epoch 1, frame 3
  EXPECT_EQ(names(g.add(done_of("a", 3, 1), 0.0)), (Names{"b@3", "a@3"}));
}

// Held past max_hold_s, the dones go out as they are: a member that stopped answering without
// leaving must not keep the others' dones from the coordinator.
TEST(DoneGather, HeldDonesGoOutAfterTheLongestHold) {
  DoneGather g(0.5);
  g.add(done_of("a", 0), 0.0);
  g.add(done_of("b", 0), 0.0);
  EXPECT_TRUE(g.add(done_of("a", 1), 10.0).empty());
  ASSERT_TRUE(g.deadline().has_value());
  EXPECT_DOUBLE_EQ(*g.deadline(), 10.5);
  EXPECT_TRUE(g.overdue(10.4).empty());
  EXPECT_EQ(names(g.overdue(10.5)), Names{"a@1"});
  EXPECT_FALSE(g.deadline().has_value());
  // b's done of that frame, when it comes, goes out at once: a answered that grant.
  EXPECT_EQ(names(g.add(done_of("b", 1), 10.6)), Names{"b@1"});
}
