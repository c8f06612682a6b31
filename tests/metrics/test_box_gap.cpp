// Box-to-box distance (the bumper gap of the convoy report) against closed-form geometry, and
// against a brute-force search over both boxes' surfaces for random poses.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "metrics/box_gap.hpp"

using namespace syndds;
using namespace syndds::metrics;

namespace {

// The HMMWV's chassis box (config/vehicles/hmmwv.yaml): 4.7 m long, 2.16 m wide, 1.1 m high,
// centred 0.45 m above the chassis reference point.
const Vec3 kHalf(2.35, 1.08, 0.55);
const Vec3 kCentre(0.0, 0.0, 0.45);

OrientedBox hmmwv(double x, double y, double yaw_rad, double z = 0.0) {
  return place_box({Vec3(x, y, z), quat_from_yaw(yaw_rad)}, kCentre, kHalf);
}

constexpr double kTol = 1e-12;

}  // namespace

TEST(BoxGap, OneBehindTheOtherIsCentreDistanceLessBothHalfLengths) {
  // The convoy case: same heading, same line; 10 m centre to centre is 10 - 4.7 = 5.3 m.
  EXPECT_NEAR(box_distance(hmmwv(0, 0, 0), hmmwv(10, 0, 0)), 5.3, kTol);
  EXPECT_NEAR(box_distance(hmmwv(10, 0, 0), hmmwv(0, 0, 0)), 5.3, kTol);  // symmetric
  // Heading north-east along the same line: the same gap.
  const double a = std::numbers::pi / 4.0;
  EXPECT_NEAR(box_distance(hmmwv(0, 0, a), hmmwv(10 * std::cos(a), 10 * std::sin(a), a)), 5.3,
              1e-9);
  // A lateral offset smaller than the width changes nothing (faces still overlap sideways).
  EXPECT_NEAR(box_distance(hmmwv(0, 0, 0), hmmwv(8, 1.5, 0)), 8 - 4.7, kTol);
}

TEST(BoxGap, OffsetSideBySideIsTheCornerToCornerDistance) {
  // Offset 6 m along and 3 m across: corners (2.35, 1.08) and (3.65, 1.92) are 1.3 x 0.84 apart.
  EXPECT_NEAR(box_distance(hmmwv(0, 0, 0), hmmwv(6, 3, 0)), std::hypot(1.3, 0.84), kTol);
  // Abreast: 3 m apart centre to centre, 3 - 2.16 = 0.84 m side to side.
  EXPECT_NEAR(box_distance(hmmwv(0, 0, 0), hmmwv(0, 3, 0)), 0.84, kTol);
}

TEST(BoxGap, ATurnedLeaderPresentsItsNearestCorner) {
  // The leader ahead, turned by theta: its nearest corner lies (L cos + W sin) back from its
  // centre, and while that corner is within the follower's width it faces the front face.
  for (const double theta : {0.1, 0.3, 0.6}) {
    SCOPED_TRACE(theta);
    const double reach = kHalf.x() * std::cos(theta) + kHalf.y() * std::sin(theta);
    const double corner_y = kHalf.x() * std::sin(theta) - kHalf.y() * std::cos(theta);
    ASSERT_LT(std::abs(corner_y), kHalf.y());
    EXPECT_NEAR(box_distance(hmmwv(0, 0, 0), hmmwv(9, 0, theta)), 9 - kHalf.x() - reach, 1e-9);
  }
  // Crossing at right angles (a T): 9 - 2.35 - 1.08.
  EXPECT_NEAR(box_distance(hmmwv(0, 0, 0), hmmwv(9, 0, std::numbers::pi / 2)), 9 - 2.35 - 1.08,
              1e-9);
}

TEST(BoxGap, PitchRaisesTheNearestEdge) {
  // A follower nose-down (pitch theta about y, braking hard): its front bottom edge drops and
  // moves forward. Boxes rotate about the chassis reference point, which the box centre sits
  // 0.45 m above; check against the rotated edge's x directly.
  const double theta = 0.05;
  const Quat pitch(Eigen::AngleAxisd(theta, Vec3::UnitY()));  // positive: nose down
  const OrientedBox f = place_box({Vec3::Zero(), pitch}, kCentre, kHalf);
  double front = -1e9;
  for (const double z : {-kHalf.z(), kHalf.z()}) {
    const Vec3 corner = pitch * (kCentre + Vec3(kHalf.x(), 0.0, z));
    front = std::max(front, corner.x());
  }
  EXPECT_NEAR(box_distance(f, hmmwv(10, 0, 0)), 10 - kHalf.x() - front, 1e-9);
}

TEST(BoxGap, OverlappingOrTouchingBoxesAreZeroApart) {
  EXPECT_EQ(box_distance(hmmwv(0, 0, 0), hmmwv(4.0, 0, 0)), 0.0);  // 0.7 m into each other
  EXPECT_EQ(box_distance(hmmwv(0, 0, 0), hmmwv(4.7, 0, 0)), 0.0);  // touching
  EXPECT_TRUE(boxes_overlap(hmmwv(0, 0, 0), hmmwv(3, 2, 0.7)));
  // An edge through a face with no corner of either box inside the other: a slab long in y, and
  // a bar long in x turned 45 degrees about x whose lowest edge (along x) runs 0.1 m below the
  // slab's top face, through its sides. Corners and edges alone would say 0.1 m apart; the
  // separating-axis test finds the overlap.
  const OrientedBox a = place_box({Vec3::Zero(), Quat::Identity()}, Vec3::Zero(), Vec3(1, 5, 1));
  const Quat roll(Eigen::AngleAxisd(std::numbers::pi / 4, Vec3::UnitX()));
  const OrientedBox b =
      place_box({Vec3(0, 0, 1 + std::sqrt(2.0) - 0.1), roll}, Vec3::Zero(), Vec3(5, 1, 1));
  EXPECT_TRUE(boxes_overlap(a, b));
  EXPECT_EQ(box_distance(a, b), 0.0);
}

TEST(BoxGap, AnEdgeAcrossAnEdge) {
  // Unit cube at the origin, and a cube turned 45 degrees about x and then about z, set above
  // the top edge x = 1, z = 1: its lowest edge (its lowest points) runs along (1, 1, 0)/sqrt2
  // at height zc - sqrt2, crossing over the cube's edge along y.
  const OrientedBox a = place_box({Vec3::Zero(), Quat::Identity()}, Vec3::Zero(), Vec3(1, 1, 1));
  const Quat q = Quat(Eigen::AngleAxisd(std::numbers::pi / 4, Vec3::UnitZ())) *
                 Quat(Eigen::AngleAxisd(std::numbers::pi / 4, Vec3::UnitX()));
  // Lowest edge of b: its local x axis at local (y, z) with the rotated z lowest.
  const double zc = 1.0 + std::sqrt(2.0) + 0.3;
  const OrientedBox b = place_box({Vec3(1.0, 0.0, zc), q}, Vec3::Zero(), Vec3(1, 1, 1));
  // That edge passes over the point (1, 0) at height zc - sqrt2 = 1.3, 0.3 above a's top face
  // and edge: the gap is 0.3.
  EXPECT_NEAR(box_distance(a, b), 0.3, 1e-12);
}

TEST(BoxGap, AgreesWithABruteForceSearchOverTheSurfaces) {
  // Random poses; the distance is checked from both sides: never more than the closest pair
  // of surface samples (exact is a lower bound of any sampled pair), and within the sampling
  // step of it.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const auto random_box = [&](double spread) {
    const Quat q = Quat(Eigen::AngleAxisd(3.0 * u(rng), Vec3(u(rng), u(rng), u(rng)).normalized()));
    return place_box({Vec3(spread * u(rng), spread * u(rng), spread * u(rng)), q}, Vec3::Zero(),
                     Vec3(0.5 + 0.5 * std::abs(u(rng)), 0.5 + 0.5 * std::abs(u(rng)),
                          0.5 + 0.5 * std::abs(u(rng))));
  };
  const auto surface = [](const OrientedBox& b, int n) {
    std::vector<Vec3> pts;
    for (int face = 0; face < 6; ++face) {
      const int axis = face / 2;
      const double side = face % 2 ? 1.0 : -1.0;
      for (int i = 0; i <= n; ++i) {
        for (int j = 0; j <= n; ++j) {
          Vec3 local;
          local[axis] = side;
          local[(axis + 1) % 3] = -1.0 + 2.0 * i / n;
          local[(axis + 2) % 3] = -1.0 + 2.0 * j / n;
          pts.push_back(b.centre + b.orientation * local.cwiseProduct(b.half_extents));
        }
      }
    }
    return pts;
  };
  int separated = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const OrientedBox a = random_box(0.0);
    const OrientedBox b = random_box(3.0);
    const double d = box_distance(a, b);
    if (d == 0.0) continue;
    ++separated;
    const int n = 24;  // grid step at most 2 / 24 of a side (<= 0.084 m)
    const auto pa = surface(a, n), pb = surface(b, n);
    double brute = 1e9;
    for (const auto& p : pa) {
      for (const auto& q : pb) brute = std::min(brute, (p - q).norm());
    }
    EXPECT_LE(d, brute + 1e-12) << trial;
    EXPECT_GE(d, brute - 0.12) << trial;  // both closest points within half a diagonal step
  }
  EXPECT_GT(separated, 20);
}
