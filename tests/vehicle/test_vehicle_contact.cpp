// Vehicle-vehicle contact (docs/vehicle-contact.md): two vehicles in separate models, each
// feeling the other as a proxy built from the other's state at the start of each frame, against
// the oracle of both in ONE ODE world with their contact solved exactly at every step.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "core/rect2.hpp"
#include "vehicle/bicycle_model.hpp"
#include "vehicle/ode_vehicle.hpp"
#include "vehicle_test_util.hpp"

namespace syndds::vehicle {
namespace {

using testing::flat;
using testing::load;

constexpr double kStep = 0.002;
int kStepsPerFrame = 5;  // heartbeat 0.01 s (a test may lengthen the frame)

PeerVehicle peer_of(const std::string& id, const std::shared_ptr<const VehicleParams>& params,
                    const VehicleSnapshot& s) {
  PeerVehicle p;
  p.id = id;
  p.params = params;
  p.pose = s.pose;
  p.linear_velocity = s.linear_velocity;
  p.angular_velocity = s.angular_velocity;
  for (const auto& w : s.wheels) p.wheels.push_back(w.pose);
  return p;
}

/// The chassis box in the ground plane (what the bumper gap and the penetration are measured on).
Rect2 chassis_rect(const VehicleParams& p, const VehicleSnapshot& s) {
  const double yaw = yaw_of(s.pose.orientation);
  const Vec3 c = s.pose.position + s.pose.orientation * p.chassis.box_centre_m;
  Rect2 r;
  r.centre = Vec2(c.x(), c.y());
  r.yaw = yaw;
  r.half_length = p.chassis.half_extents_m.x();
  r.half_width = p.chassis.half_extents_m.y();
  return r;
}

double momentum_x(const VehicleParams& p, const VehicleSnapshot& s) {
  return p.total_mass_kg() * s.linear_velocity.x();
}

double kinetic_energy(const VehicleParams& p, const VehicleSnapshot& s) {
  return 0.5 * p.total_mass_kg() * s.linear_velocity.squaredNorm();
}

struct Outcome {
  double momentum_before = 0.0;
  double momentum_after = 0.0;
  double energy_before = 0.0;
  double energy_after = 0.0;
  double max_penetration = 0.0;  // chassis boxes, at frame ends
  double min_gap = 1e9;          // chassis boxes, at frame ends
  std::vector<CollisionContact> events_a, events_b;
};

struct PairCase {
  std::string model = "full";
  Pose start_a, start_b;
  double speed_a = 0.0, speed_b = 0.0;  // forward speeds at the start
  double seconds = 3.0;
  double before_s = 0.2;                // momentum "before" sampled here (no contact yet)
};

Pose pose_at(double x, double yaw) {
  Pose p;
  p.position = Vec3(x, 0.0, 0.0);
  p.orientation = quat_from_yaw(yaw);
  return p;
}

void record(Outcome& o, const VehicleParams& p, const VehicleSnapshot& a, const VehicleSnapshot& b,
            double t, const PairCase& c) {
  const RectOverlap ov = rect_overlap(chassis_rect(p, a), chassis_rect(p, b));
  o.max_penetration = std::max(o.max_penetration, ov.depth);
  o.min_gap = std::min(o.min_gap, rect_distance(chassis_rect(p, a), chassis_rect(p, b)));
  const double m = momentum_x(p, a) + momentum_x(p, b);
  const double e = kinetic_energy(p, a) + kinetic_energy(p, b);
  if (std::abs(t - c.before_s) < 1e-9) {
    o.momentum_before = m;
    o.energy_before = e;
  }
  o.momentum_after = m;
  o.energy_after = e;
}

std::unique_ptr<VehicleModel> make(const PairCase& c, const VehicleParams& p, const Pose& start,
                                   double speed) {
  if (c.model == "full") {
    auto m = std::make_unique<OdeVehicleModel>(p, start, flat());
    m->set_speed(speed);
    return m;
  }
  auto m = std::make_unique<BicycleModel>(p, start, flat());
  m->set_speed(speed);
  return m;
}

/// Each model in its own world, the other one a proxy of its state at the start of each frame
/// (what VehicleAgent does with the bodies the barrier passes on); with `every_step` the
/// proxies are refreshed at every step instead (no frame lag: the reduced model's oracle).
Outcome run_separate(const PairCase& c, bool every_step = false) {
  const auto params = std::make_shared<const VehicleParams>(load("hmmwv"));
  auto a = make(c, *params, c.start_a, c.speed_a);
  auto b = make(c, *params, c.start_b, c.speed_b);
  Outcome o;
  const int frames = static_cast<int>(std::lround(c.seconds / (kStep * kStepsPerFrame)));
  const int exchanges = every_step ? kStepsPerFrame : 1;
  for (int f = 1; f <= frames; ++f) {
    for (int x = 0; x < exchanges; ++x) {
      const VehicleSnapshot sa = a->snapshot();
      const VehicleSnapshot sb = b->snapshot();
      a->set_peers({peer_of("b", params, sb)});
      b->set_peers({peer_of("a", params, sa)});
      for (int k = 0; k < kStepsPerFrame / exchanges; ++k) a->advance(kStep);
      for (int k = 0; k < kStepsPerFrame / exchanges; ++k) b->advance(kStep);
    }
    for (auto& e : a->take_collisions()) o.events_a.push_back(e);
    for (auto& e : b->take_collisions()) o.events_b.push_back(e);
    record(o, *params, a->snapshot(), b->snapshot(), f * kStep * kStepsPerFrame, c);
  }
  return o;
}

/// The oracle: both full vehicles in one ODE world, their contact in the same LCP every step.
Outcome run_one_world(const PairCase& c) {
  const VehicleParams params = load("hmmwv");
  auto a = std::make_unique<OdeVehicleModel>(params, c.start_a, flat());
  auto b = OdeVehicleModel::in_world_of(*a, params, c.start_b, flat());
  a->set_speed(c.speed_a);
  b->set_speed(c.speed_b);
  Outcome o;
  const int frames = static_cast<int>(std::lround(c.seconds / (kStep * kStepsPerFrame)));
  for (int f = 1; f <= frames; ++f) {
    for (int k = 0; k < kStepsPerFrame; ++k) OdeVehicleModel::step_pair(*a, *b, kStep);
    record(o, params, a->snapshot(), b->snapshot(), f * kStep * kStepsPerFrame, c);
  }
  b.reset();  // before its host
  return o;
}

PairCase head_on(const std::string& model) {
  PairCase c;
  c.model = model;
  c.start_a = pose_at(0.0, 0.0);
  c.start_b = pose_at(9.0, std::numbers::pi);
  c.speed_a = 5.0;
  c.speed_b = 5.0;
  return c;
}

PairCase rear_end(const std::string& model) {
  PairCase c;
  c.model = model;
  c.start_a = pose_at(0.0, 0.0);
  c.start_b = pose_at(9.0, 0.0);
  c.speed_a = 8.0;
  c.speed_b = 2.0;
  return c;
}

void expect_contact_like_reference(const Outcome& got, const Outcome& ref, double momentum_scale,
                                   const char* what) {
  SCOPED_TRACE(what);
  std::printf("%s: separate p %.0f -> %.0f, E %.0f -> %.0f, pen %.4f gap %.4f | reference p %.0f -> "
              "%.0f, E %.0f -> %.0f, pen %.4f gap %.4f | events a %zu b %zu (J %.0f, v %.2f)\n",
              what, got.momentum_before, got.momentum_after, got.energy_before, got.energy_after,
              got.max_penetration, got.min_gap, ref.momentum_before, ref.momentum_after,
              ref.energy_before, ref.energy_after, ref.max_penetration, ref.min_gap,
              got.events_a.size(), got.events_b.size(),
              got.events_a.empty() ? 0.0 : got.events_a.front().impulse_ns,
              got.events_a.empty() ? 0.0 : got.events_a.front().relative_speed_mps);
  // They met, and did not pass through each other.
  EXPECT_LE(got.min_gap, 0.05);
  EXPECT_LE(got.max_penetration, 0.05);
  EXPECT_LE(ref.max_penetration, 0.05);
  ASSERT_FALSE(got.events_a.empty());
  ASSERT_FALSE(got.events_b.empty());
  EXPECT_EQ(got.events_a.front().other_vehicle, "b");
  EXPECT_EQ(got.events_b.front().other_vehicle, "a");
  EXPECT_TRUE(got.events_a.front().obstacle_id.empty());
  EXPECT_GT(got.events_a.front().relative_speed_mps, 1.0);
  EXPECT_GT(got.events_a.front().impulse_ns, 0.0);
  // Momentum after the contact within 10 % of the one-world reference (of the momentum one
  // vehicle brings in when the reference's total is near zero, head-on).
  EXPECT_NEAR(got.momentum_after, ref.momentum_after, 0.1 * momentum_scale)
      << "before " << got.momentum_before << " (reference " << ref.momentum_before << ")";
  // Energy: dissipated as in the reference, within 10 % of the energy brought in.
  EXPECT_NEAR(got.energy_after, ref.energy_after, 0.1 * got.energy_before);
  EXPECT_LT(got.energy_after, got.energy_before);
}

TEST(VehicleContact, FullHeadOnStopsBothLikeOneWorld) {
  const PairCase c = head_on("full");
  const Outcome got = run_separate(c);
  const Outcome ref = run_one_world(c);
  const double m = load("hmmwv").total_mass_kg();
  expect_contact_like_reference(got, ref, m * 5.0, "head-on");
  // Both stopped against each other.
  EXPECT_LT(std::abs(got.momentum_after), 0.1 * m * 5.0);
  EXPECT_LT(got.energy_after, 0.1 * got.energy_before);
}

TEST(VehicleContact, FullRearEndSharesMomentumLikeOneWorld) {
  const PairCase c = rear_end("full");
  const Outcome got = run_separate(c);
  const Outcome ref = run_one_world(c);
  expect_contact_like_reference(got, ref, std::abs(ref.momentum_after), "rear-end");
}

TEST(VehicleContact, ReducedHeadOnStopsBoth) {
  const PairCase c = head_on("reduced");
  const Outcome got = run_separate(c);
  const Outcome ref = run_separate(c, true);
  const double m = load("hmmwv").total_mass_kg();
  expect_contact_like_reference(got, ref, m * 5.0, "reduced head-on");
  EXPECT_LT(got.energy_after, 0.1 * got.energy_before);
}

TEST(VehicleContact, ReducedRearEndSharesMomentum) {
  const PairCase c = rear_end("reduced");
  const Outcome got = run_separate(c);
  const Outcome ref = run_separate(c, true);
  expect_contact_like_reference(got, ref, std::abs(ref.momentum_after), "reduced rear-end");
}

TEST(VehicleContact, TheLagErrorStaysBoundedWithFiveTimesLongerFrames) {
  // Heartbeat 0.05 s: the proxy stands in for the other vehicle five times longer.
  kStepsPerFrame = 25;
  const PairCase c = rear_end("full");
  const Outcome got = run_separate(c);
  const Outcome ref = run_one_world(c);
  kStepsPerFrame = 5;
  expect_contact_like_reference(got, ref, std::abs(ref.momentum_after), "rear-end, 50 ms frames");
}

TEST(VehicleContact, NoPeersNoChange) {
  // A peer far away changes nothing, bit for bit (its proxy is an island of its own).
  const auto params = std::make_shared<const VehicleParams>(load("hmmwv"));
  OdeVehicleModel a(*params, pose_at(0.0, 0.0), flat());
  OdeVehicleModel b(*params, pose_at(0.0, 0.0), flat());
  OdeVehicleModel far(*params, pose_at(100.0, 0.0), flat());
  a.set_speed(5.0);
  b.set_speed(5.0);
  for (int f = 0; f < 100; ++f) {
    a.set_peers({peer_of("far", params, far.snapshot())});
    for (int k = 0; k < kStepsPerFrame; ++k) {
      a.advance(kStep);
      b.advance(kStep);
    }
  }
  EXPECT_EQ(a.snapshot().pose.position, b.snapshot().pose.position);
  EXPECT_TRUE(a.take_collisions().empty());
}

}  // namespace
}  // namespace syndds::vehicle
