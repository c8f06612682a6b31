// Soil routing's bookkeeping (agents/soil_routing.hpp): when a vehicle's box is renewed, when a
// published box takes effect, and the boxes of the others.
#include <gtest/gtest.h>

#include "agents/soil_routing.hpp"

using namespace syndds;
using namespace syndds::agents;

namespace {

scm::ScmParams params() {
  scm::ScmParams p;
  p.grid.spacing_m = 0.05;
  p.grid.x_min_m = -100;
  p.grid.x_max_m = 100;
  p.grid.y_min_m = -100;
  p.grid.y_max_m = 100;
  return p;
}

}  // namespace

// The box covers the interest square grown by twice the margin and is renewed only when the
// square grown by one margin leaves it; a box published in frame p is in effect from frame
// p + 2, and only boxes after the first are loaded (the first starts on untouched soil).
TEST(SoilRouting, ABoxIsRenewedWithHysteresisAndTakesEffectTwoFramesLater) {
  const scm::ScmTerrain soil(params());
  SoilSubscription sub(12.0);
  const auto first = sub.renew(0, soil, 0.0, 0.0);
  ASSERT_TRUE(first);
  EXPECT_EQ(first->i_lo, scm::Replication::tiles_of(soil.interest_box(0, 0, 16.0)).i_lo);
  EXPECT_FALSE(sub.renew(1, soil, 1.0, 0.0));  // within the margin: no change
  EXPECT_TRUE(sub.begin_frame(1).empty());
  EXPECT_TRUE(sub.begin_frame(2).empty());  // the first box takes effect, nothing to load
  sub.check_covers("v", 2, soil.interest_box(1.0, 0.0, 12.0));
  const auto second = sub.renew(2, soil, 4.0, 0.0);  // the square + margin reaches x = 18 m
  ASSERT_TRUE(second);
  EXPECT_GT(second->i_hi, first->i_hi);
  EXPECT_TRUE(sub.begin_frame(3).empty());
  // In frame 3 the writers still use the first box: a square beyond it is an error.
  EXPECT_THROW(sub.check_covers("v", 3, soil.interest_box(8.0, 0.0, 12.0)), std::runtime_error);
  const auto due = sub.begin_frame(4);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].frame, 2);
  EXPECT_EQ(due[0].before.i_hi, first->i_hi);
  EXPECT_EQ(due[0].now.i_hi, second->i_hi);
  sub.check_covers("v", 4, soil.interest_box(4.0, 0.0, 12.0));
  try {
    sub.check_covers("vehicle a", 4, soil.interest_box(40.0, 0.0, 12.0));
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("vehicle a: in frame 4"), std::string::npos) << e.what();
  }
}

// The state round trip keeps the box, the box in effect and the changes not yet loaded.
TEST(SoilRouting, StateRoundTrip) {
  const scm::ScmTerrain soil(params());
  SoilSubscription a(12.0), b(12.0);
  a.renew(0, soil, 0.0, 0.0);
  a.begin_frame(2);
  a.renew(5, soil, 10.0, 0.0);
  core::StateWriter w;
  a.save_state(w);
  core::StateReader r(w.bytes(), "test");
  b.load_state(r);
  EXPECT_EQ(b.box().i_hi, a.box().i_hi);
  const auto due = b.begin_frame(7);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].frame, 5);
}

// The others' boxes: one change per sample, the vehicle's own samples skipped, the box before
// empty for a vehicle's first.
TEST(SoilRouting, PeerBoxesReportEachChange) {
  SoilBoxes boxes;
  const std::vector<proto::SoilInterestMsg> first = {{"a", "vehicle/a", 0, 0, 3, 0, 3},
                                                     {"b", "vehicle/b", 0, 5, 8, 0, 3}};
  auto changes = boxes.update(first, "b");
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].vehicle_id, "a");
  EXPECT_TRUE(box_empty(changes[0].before));
  changes = boxes.update({{"a", "vehicle/a", 9, 1, 4, 0, 3}}, "b");
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].before.i_hi, 3);
  EXPECT_EQ(changes[0].now.i_hi, 4);
  EXPECT_EQ(boxes.boxes().size(), 1u);
}
