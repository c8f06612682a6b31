// The broad phase of vehicle-vehicle contact (docs/vehicle-contact.md) and its trip through the
// barrier: FrameDone(k-1).body -> FrameGrant(k).bodies, only for vehicles within reach.
#include <gtest/gtest.h>

#include <numbers>

#include "protocol/barrier.hpp"
#include "protocol/contact_bodies.hpp"

using namespace syndds;
using namespace syndds::proto;
using Kind = Barrier::Action::Kind;

namespace {

// An HMMWV-sized footprint (4.7 m x 2.8 m) at (x, y), heading `yaw`, moving at `speed`.
VehicleBodyMsg body(const std::string& id, double x, double y, double yaw = 0.0,
                    double speed = 0.0) {
  VehicleBodyMsg b;
  b.vehicle_id = id;
  b.pose.position = Vec3(x, y, 0.5);
  b.pose.orientation = quat_from_yaw(yaw);
  b.linear_velocity = speed * Vec3(std::cos(yaw), std::sin(yaw), 0.0);
  b.footprint_offset_m = 0.0;
  b.footprint_half_length_m = 2.35;
  b.footprint_half_width_m = 1.4;
  return b;
}

std::vector<std::string> ids(const std::vector<VehicleBodyMsg>& bodies) {
  std::vector<std::string> out;
  for (const auto& b : bodies) out.push_back(b.vehicle_id);
  return out;
}

}  // namespace

TEST(ContactBodies, LanesFiveMetresApartAreOutOfReachAtRest) {
  // 2 x 1.4 m half widths leave 2.2 m between lanes: more than the 0.5 m margin.
  const auto out = select_contact_bodies({body("a", 0, 0), body("b", 0, 5), body("c", 0, 10)}, 0.01);
  EXPECT_TRUE(out.empty());
}

TEST(ContactBodies, TheMarginGrowsWithWhatBothCanTravelInTwoFrames) {
  // 1 m apart end to end: out of reach at rest (margin 0.5 m), within reach when closing at
  // 15 m/s each (0.5 + 2 x 0.01 x 30 = 1.1 m).
  const double x = 2 * 2.35 + 1.0;
  EXPECT_TRUE(select_contact_bodies({body("a", 0, 0), body("b", x, 0)}, 0.01).empty());
  EXPECT_EQ(ids(select_contact_bodies({body("a", 0, 0, 0, 15), body("b", x, 0, std::numbers::pi, 15)},
                                      0.01)),
            (std::vector<std::string>{"a", "b"}));
}

TEST(ContactBodies, OnlyVehiclesNearAnotherAreSelectedSortedById) {
  const auto out = select_contact_bodies(
      {body("z", 100, 0), body("m", 5.0, 0.2), body("b", 0, 0), body("q", 0, 50)}, 0.01);
  EXPECT_EQ(ids(out), (std::vector<std::string>{"b", "m"}));
}

TEST(ContactBodies, RotatedFootprintsUseTheirOrientation) {
  // End to end 5.0 m apart (0.3 m between them): within reach; turned north side by side at
  // 5.5 m (2.7 m between their sides): not, though their centres are about as far apart.
  EXPECT_TRUE(within_reach(body("a", 0, 0), body("b", 5.0, 0), 0.01));
  EXPECT_FALSE(within_reach(body("a", 0, 0, std::numbers::pi / 2),
                            body("b", 5.5, 0, std::numbers::pi / 2), 0.01));
  EXPECT_TRUE(within_reach(body("a", 0, 0), body("b", 0, 3.0), 0.01));  // sides overlap
}

TEST(ContactBodies, TheBarrierPassesTheBodiesOfFrameKMinusOneWithGrantK) {
  BarrierConfig c;
  c.members = {"vehicle/a", "vehicle/b", "vehicle/c", "recorder"};
  c.final_frame = 3;
  c.heartbeat_s = 0.01;
  Barrier barrier(c, 0.0);
  for (const auto& m : c.members) barrier.on_join(m, 0.0);
  ASSERT_EQ(barrier.poll(0.0).kind, Kind::grant);
  auto done = [](const std::string& member, std::vector<VehicleBodyMsg> body) {
    FrameDoneMsg d;
    d.member_id = member;
    d.frame = 0;
    d.body = std::move(body);
    return d;
  };
  barrier.on_done(done("vehicle/a", {body("a", 0, 0)}), 0.0);
  barrier.on_done(done("vehicle/b", {body("b", 5.0, 0)}), 0.0);
  barrier.on_done(done("vehicle/c", {body("c", 0, 40)}), 0.0);
  // A member that reports someone else's body: the done counts, the body is dropped.
  EXPECT_NE(barrier.on_done(done("recorder", {body("c", 5.0, 1.0)}), 0.0), "");
  const auto a = barrier.poll(0.0);
  ASSERT_EQ(a.kind, Kind::grant);
  EXPECT_EQ(a.grant.frame, 1);
  EXPECT_EQ(ids(a.grant.bodies), (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(a.grant.bodies[1].pose.position.x(), 5.0);
  // Frame 1's dones report none near: the next grant carries none (nothing stays from before).
  for (const auto& m : c.members) {
    FrameDoneMsg d = done(m, {});
    d.frame = 1;
    barrier.on_done(d, 0.0);
  }
  const auto g2 = barrier.poll(0.0);
  ASSERT_EQ(g2.kind, Kind::grant);
  EXPECT_TRUE(g2.grant.bodies.empty());
}
