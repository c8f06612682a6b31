#include <gtest/gtest.h>

#include "protocol/frame_inbox.hpp"

using namespace syndds::proto;

namespace {
VehicleStateMsg state(const std::string& id, std::int64_t frame, double x = 0) {
  VehicleStateMsg s;
  s.vehicle_id = id;
  s.source = "vehicle/" + id;
  s.frame = frame;
  s.pose.position.x() = x;
  return s;
}
}  // namespace

// The data barrier: a grant whose manifest announces a sample is not enough; the inbox must
// hold the sample itself before the frame may start.
TEST(FrameInbox, IncompleteUntilEveryAnnouncedSampleArrived) {
  FrameInbox inbox({{Topic::vehicle_state, ""}});
  const Manifest manifest = {{Topic::vehicle_state, "a", "vehicle/a", 1},
                             {Topic::vehicle_state, "b", "vehicle/b", 1}};
  EXPECT_FALSE(inbox.complete(4, manifest));
  inbox.add(state("b", 4));
  EXPECT_FALSE(inbox.complete(4, manifest));
  EXPECT_EQ(inbox.describe_missing(4, manifest), "vehicle_state key=a from vehicle/a: have 0 of 1");
  inbox.add(state("a", 5));  // a sample of the wrong frame does not count
  EXPECT_FALSE(inbox.complete(4, manifest));
  inbox.add(state("a", 4));
  EXPECT_TRUE(inbox.complete(4, manifest));
}

// Enough samples in number is not enough: each announced entry needs its own. A sample that
// no entry announces (here a second one from b) must not stand in for a's.
TEST(FrameInbox, AsManySamplesAsAnnouncedButOneEntryShortIsIncomplete) {
  FrameInbox inbox({{Topic::vehicle_state, ""}});
  const Manifest manifest = {{Topic::vehicle_state, "a", "vehicle/a", 1},
                             {Topic::vehicle_state, "b", "vehicle/b", 1}};
  inbox.add(state("b", 4));
  inbox.add(state("b", 4));
  EXPECT_FALSE(inbox.complete(4, manifest));
  inbox.add(state("a", 4));
  EXPECT_TRUE(inbox.complete(4, manifest));
}

TEST(FrameInbox, OnlySubscribedEntriesAreNeeded) {
  FrameInbox inbox({{Topic::driver_command, "a"}});
  const Manifest manifest = {{Topic::vehicle_state, "a", "vehicle/a", 1},
                             {Topic::driver_command, "b", "controller/b", 1}};
  EXPECT_TRUE(inbox.needed(manifest).empty());
  EXPECT_TRUE(inbox.complete(0, manifest));
  EXPECT_FALSE(inbox.add(state("a", 0)));
}

TEST(FrameInbox, TakeReturnsCanonicalOrderAndForgetsOldFrames) {
  FrameInbox inbox({{Topic::vehicle_state, ""}});
  const Manifest manifest = {{Topic::vehicle_state, "a", "vehicle/a", 1},
                             {Topic::vehicle_state, "b", "vehicle/b", 1}};
  inbox.add(state("b", 2, 2.0));
  inbox.add(state("a", 2, 1.0));
  inbox.add(state("a", 3, 3.0));
  auto f = inbox.take(2, manifest);
  ASSERT_EQ(f.vehicle_states.size(), 2u);
  EXPECT_EQ(f.vehicle_states[0].vehicle_id, "a");
  EXPECT_EQ(f.vehicle_states[1].vehicle_id, "b");
  EXPECT_FALSE(inbox.add(state("a", 2)));  // late duplicate of a consumed frame
  auto g = inbox.take(3, {{Topic::vehicle_state, "a", "vehicle/a", 1}});
  ASSERT_EQ(g.vehicle_states.size(), 1u);
  EXPECT_DOUBLE_EQ(g.vehicle_states[0].pose.position.x(), 3.0);
}

TEST(FrameInbox, UnannouncedSamplesAreDroppedAndCounted) {
  FrameInbox inbox({{Topic::vehicle_state, ""}});
  inbox.add(state("a", 1));
  inbox.add(state("z", 1));
  auto f = inbox.take(1, {{Topic::vehicle_state, "a", "vehicle/a", 1}});
  EXPECT_EQ(f.vehicle_states.size(), 1u);
  EXPECT_EQ(inbox.unexpected_samples(), 1u);
}

// Manifest entries travel with the topic's name: every data topic's name is its TopicTraits
// name and reads back as the same topic; anything else is refused.
TEST(TopicNames, EveryTopicReadsBackFromItsName) {
  std::size_t seen = 0;
  for_each_topic([&](auto t) {
    constexpr Topic T = decltype(t)::value;
    EXPECT_EQ(to_string(T), TopicTraits<T>::name);
    Topic back = T == Topic::vehicle_state ? Topic::driver_command : Topic::vehicle_state;
    ASSERT_TRUE(topic_from_string(TopicTraits<T>::name, back)) << TopicTraits<T>::name;
    EXPECT_EQ(back, T);
    ++seen;
  });
  EXPECT_EQ(seen, std::size(kAllDataTopics));
  Topic untouched = Topic::imu;
  EXPECT_FALSE(topic_from_string("vehicle_stat", untouched));
  EXPECT_FALSE(topic_from_string("vehicle_state ", untouched));
  EXPECT_FALSE(topic_from_string("", untouched));
  EXPECT_EQ(untouched, Topic::imu);
  EXPECT_EQ(to_string(static_cast<Topic>(250)), "unknown");
}

// What the DDS layer matches a member's reader with: a follower that needs the V2V of the
// vehicle ahead and of its convoy's head is matched with those two writers, not every vehicle's.
TEST(Subscriptions, KeysOfATopicAreTheListedOnesOrEveryKey) {
  const std::vector<Subscription> follower{{Topic::v2v_message, "head"},
                                           {Topic::vehicle_state, "me"},
                                           {Topic::v2v_message, "ahead"},
                                           {Topic::v2v_message, "head"}};
  EXPECT_EQ(subscribed_keys(follower, Topic::v2v_message),
            (std::vector<std::string>{"ahead", "head"}));
  EXPECT_EQ(subscribed_keys(follower, Topic::vehicle_state), (std::vector<std::string>{"me"}));
  EXPECT_TRUE(subscribed_keys(follower, Topic::driver_command).empty());  // not subscribed
  auto recorder = follower;
  recorder.push_back({Topic::v2v_message, ""});
  EXPECT_TRUE(subscribed_keys(recorder, Topic::v2v_message).empty());  // every key
}
