// The split pieces of the SCM on their own: the per-vertex soil law on one vertex against the
// closed forms (Bekker-Wong pressure-sinkage, Janosi-Hanamoto shear, elastic unloading), the
// vertex storage, bulldozing of one patch and the replication order. The whole-terrain oracles are
// in test_scm_oracles.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "scm/bulldozing.hpp"
#include "scm/contact_patch.hpp"
#include "scm/replication.hpp"
#include "scm/soil_law.hpp"
#include "scm/vertex_grid.hpp"
#include "scm_test_util.hpp"

using namespace syndds;
using namespace syndds::scm;

namespace {

constexpr double kCellArea = 0.05 * 0.05;

/// A frictional-cohesive soil with every term of the law non-zero.
SoilParams soil() {
  SoilParams s;
  s.bekker_kphi = 0.8e6;
  s.bekker_kc = 0.14e5;
  s.bekker_n = 1.0 / 1.1;
  s.cohesion_pa = 1.5e3;
  s.friction_angle_deg = 27.0;
  s.janosi_shear_m = 0.02;
  s.elastic_stiffness_pa_per_m = 4e7;
  s.damping_pa_s_per_m = 3e4;
  return s;
}

/// A flat body bottom (normal straight down) at height z, moving with `velocity`.
ContactPoint flat_point(double z, const Vec3& velocity = Vec3::Zero()) {
  ContactPoint p;
  p.z_hit = z;
  p.velocity = velocity;
  p.normal = -Vec3::UnitZ();
  p.arm = Vec3(0.1, 0.2, -0.3);
  p.slope_cap = 10.0;
  return p;
}

VertexRecord undeformed(double level = 0.0) {
  VertexRecord r;
  r.level = r.level_initial = level;
  return r;
}

}  // namespace

TEST(ScmSoilLaw, FirstLoadingFollowsBekkerWong) {
  const SoilParams s = soil();
  const SoilLaw law(s, 0.0, kCellArea);
  for (const double b : {0.1, 0.25, 1.0}) {
    for (const double z : {0.005, 0.03, 0.12}) {
      VertexRecord r = undeformed();
      const VertexLoad l = law.apply(r, flat_point(-z), 1.0 / b, 0, test::kStepS);
      const double p = (s.bekker_kc / b + s.bekker_kphi) * std::pow(z, s.bekker_n);
      ASSERT_TRUE(l.loaded);
      EXPECT_NEAR(l.force.z(), p * kCellArea, 1e-12 * p * kCellArea) << "b " << b << " z " << z;
      EXPECT_NEAR(law.bekker_pressure(1.0 / b, z), p, 1e-12 * p);
      EXPECT_DOUBLE_EQ(l.sinkage, z);
      // The state: plastic sinkage leaves the elastic part p / Ke; the yield limit is p.
      EXPECT_NEAR(r.sinkage_plastic, z - p / s.elastic_stiffness_pa_per_m, 1e-15);
      EXPECT_NEAR(r.sigma_yield, p, 1e-12 * p);
      EXPECT_DOUBLE_EQ(r.level, -z);
      EXPECT_NEAR(r.step_plastic_flow, r.sinkage_plastic, 1e-15);
      // At rest on a flat bottom: no horizontal force, torque = arm x force.
      EXPECT_EQ(l.force.x(), 0.0);
      EXPECT_EQ(l.force.y(), 0.0);
      EXPECT_TRUE(l.torque.isApprox(flat_point(-z).arm.cross(l.force)));
    }
  }
}

TEST(ScmSoilLaw, UnloadingIsElasticAndTensionFree) {
  const SoilParams s = soil();
  const SoilLaw law(s, 0.0, kCellArea);
  VertexRecord r = undeformed();
  law.apply(r, flat_point(-0.05), 4.0, 0, test::kStepS);
  const double plastic = r.sinkage_plastic, yield = r.sigma_yield;
  // Back off by half the elastic rebound: stress Ke (s - s_p), state unchanged.
  const double z = 0.05 - 0.5 * (0.05 - plastic);
  const VertexLoad l = law.apply(r, flat_point(-z), 4.0, 1, test::kStepS);
  const double expect = s.elastic_stiffness_pa_per_m * (z - plastic);
  EXPECT_NEAR(l.force.z(), expect * kCellArea, 1e-9 * expect * kCellArea);
  EXPECT_LT(l.force.z(), yield * kCellArea);
  EXPECT_EQ(r.sinkage_plastic, plastic);
  EXPECT_EQ(r.sigma_yield, yield);
  EXPECT_EQ(r.step_plastic_flow, 0.0);
  // Above the plastic surface: no load at all (the soil does not pull).
  const VertexLoad none = law.apply(r, flat_point(-0.5 * plastic), 4.0, 2, test::kStepS);
  EXPECT_FALSE(none.loaded);
  EXPECT_EQ(none.force, Vec3::Zero());
}

TEST(ScmSoilLaw, ShearFollowsJanosiHanamoto) {
  const SoilParams s = soil();
  const SoilLaw law(s, 0.0, kCellArea);  // no shear damping: the plain law
  const double z = 0.04, v = 0.5;        // sliding along +x at constant sinkage
  VertexRecord r = undeformed();
  const double p = law.bekker_pressure(0.0, z);
  for (int k = 0; k < 40; ++k) {
    const VertexLoad l = law.apply(r, flat_point(-z, Vec3(v, 0.0, 0.0)), 0.0, k, test::kStepS);
    const double j = (k + 1) * v * test::kStepS;  // slip so far
    const double tau = (s.cohesion_pa + p * std::tan(deg_to_rad(s.friction_angle_deg))) *
                       (1.0 - std::exp(-j / s.janosi_shear_m));
    ASSERT_TRUE(l.loaded);
    EXPECT_NEAR(l.force.z(), p * kCellArea, 1e-9 * p * kCellArea) << k;
    EXPECT_NEAR(-l.force.x(), tau * kCellArea, 1e-9 * tau * kCellArea + 1e-12) << "step " << k;
    EXPECT_NEAR(l.force.y(), 0.0, 1e-15);
  }
  EXPECT_NEAR(law.shear_strength(p), s.cohesion_pa + p * law.tan_phi(), 1e-9);
}

TEST(ScmSoilLaw, ShearResetsAfterLeavingContact) {
  const SoilLaw law(soil(), 0.0, kCellArea);
  VertexRecord r = undeformed();
  const ContactPoint sliding = flat_point(-0.04, Vec3(0.5, 0.0, 0.0));
  const VertexLoad first = law.apply(r, sliding, 0.0, 0, test::kStepS);
  law.apply(r, sliding, 0.0, 1, test::kStepS);
  // Step 2 is skipped (no contact): step 3 starts from zero mobilisation again.
  const VertexLoad again = law.apply(r, sliding, 0.0, 3, test::kStepS);
  EXPECT_NEAR(again.force.x(), first.force.x(), 1e-12 * std::abs(first.force.x()));
}

TEST(ScmSoilLaw, ShearDampingLooksAheadAlongTheSlip) {
  const SoilParams s = soil();
  const double beta = 0.005;
  const SoilLaw law(s, beta, kCellArea);
  const ShearMobilisation m = law.mobilise(0.0, 0.0, 1e-3, 0.0, test::kStepS);
  const double K = s.janosi_shear_m;
  EXPECT_NEAR(m.mx, 1.0 - std::exp(-1e-3 / K), 1e-15);
  // The force's mobilisation is the state after a further slip |v| beta = (1e-3 / dt) beta.
  EXPECT_NEAR(m.force_mx, 1.0 - std::exp(-(1e-3 + 1e-3 / test::kStepS * beta) / K), 1e-14);
  EXPECT_EQ(m.my, 0.0);
  // No slip: the state stands still and the force uses it unchanged.
  const ShearMobilisation rest = law.mobilise(0.3, -0.2, 0.0, 0.0, test::kStepS);
  EXPECT_EQ(rest.mx, 0.3);
  EXPECT_EQ(rest.force_my, -0.2);
}

TEST(ScmSoilLaw, DampingActsOnTheVerticalStressOnly) {
  const SoilParams s = soil();
  const SoilLaw law(s, 0.0, kCellArea);
  VertexRecord a = undeformed(), b = undeformed();
  const double vz = -0.2;  // moving down: the damping adds to the vertical stress
  const VertexLoad still = law.apply(a, flat_point(-0.03), 0.0, 0, test::kStepS);
  const VertexLoad moving =
      law.apply(b, flat_point(-0.03, Vec3(0.0, 0.0, vz)), 0.0, 0, test::kStepS);
  EXPECT_NEAR(moving.force.z() - still.force.z(), -vz * s.damping_pa_s_per_m * kCellArea, 1e-9);
  EXPECT_EQ(a.sigma_yield, b.sigma_yield);  // the yield limit is the soil's, undamped
}

TEST(ScmSoilLaw, SlopedBodySurfacePushesAlongItsNormal) {
  const SoilLaw law(soil(), 0.0, kCellArea);
  VertexRecord r = undeformed();
  ContactPoint p = flat_point(-0.03);
  p.normal = Vec3(0.6, 0.0, -0.8);  // slope 0.75: the soil pushes the body towards -x
  const VertexLoad l = law.apply(r, p, 0.0, 0, test::kStepS);
  EXPECT_NEAR(l.force.x(), -0.75 * l.force.z(), 1e-12 * l.force.z());
  p.slope_cap = 0.5;  // a capped slope
  VertexRecord r2 = undeformed();
  const VertexLoad capped = law.apply(r2, p, 0.0, 0, test::kStepS);
  EXPECT_NEAR(capped.force.x(), -0.5 * capped.force.z(), 1e-12 * capped.force.z());
}

TEST(ScmVertexGrid, StoresOnlyTouchedVerticesAndTracksChanges) {
  GridParams g;
  g.spacing_m = 0.1;
  g.x_min_m = -1.0;
  g.x_max_m = 1.0;
  g.y_min_m = -0.5;
  g.y_max_m = 0.5;
  g.base_height_m = 0.25;
  VertexGrid grid(g, nullptr);
  EXPECT_EQ(grid.i_min(), -10);
  EXPECT_EQ(grid.i_max(), 10);
  EXPECT_EQ(grid.j_min(), -5);
  EXPECT_EQ(grid.j_max(), 5);
  EXPECT_TRUE(grid.in_area(10, -5));
  EXPECT_FALSE(grid.in_area(11, 0));
  EXPECT_EQ(grid.level_bound(), 0.25);
  EXPECT_EQ(grid.find(3, 4), -1);
  EXPECT_EQ(grid.level_of(3, 4), 0.25);

  const std::int32_t a = grid.get_or_insert(3, 4);
  EXPECT_EQ(grid.get_or_insert(3, 4), a);
  EXPECT_EQ(grid.size(), 1u);
  EXPECT_EQ(grid.record(a).level_initial, 0.25);
  grid.record(a).level = 0.1;
  EXPECT_EQ(grid.level_of(3, 4), 0.1);
  const std::int32_t b = grid.get_or_insert_blank(-2, 1);  // blank: not dirty
  VertexChange c;
  c.i = -2;
  c.j = 1;
  c.level_m = 0.4;
  c.level_initial_m = 0.5;
  grid.assign(grid.record(b), c);
  EXPECT_EQ(grid.level_bound(), 0.5);  // raised by the unloaded surface
  EXPECT_EQ(to_change(grid.record(b)), c);

  std::vector<std::int32_t> taken;
  grid.take_dirty([&](const VertexRecord& r) { taken.push_back(grid.find(r.i, r.j)); });
  EXPECT_EQ(taken, std::vector<std::int32_t>{a});
  grid.take_dirty([&](const VertexRecord&) { ADD_FAILURE() << "dirty list not cleared"; });
  grid.clear();
  EXPECT_EQ(grid.size(), 0u);
  EXPECT_EQ(grid.find(3, 4), -1);
  EXPECT_EQ(grid.level_bound(), 0.25);
}

// One loaded contact vertex at (0, 0) that pressed `flow` down plastically this step.
ContactPatches one_vertex_patch(VertexGrid& grid, double flow) {
  ContactPatches s;
  StepVertex v;
  v.i = 0;
  v.j = 0;
  v.body = 0;
  v.contact = 0;
  v.patch = 0;
  v.z_hit = -flow;
  v.record = grid.get_or_insert(0, 0);
  grid.record(v.record).step_plastic_flow = flow;
  grid.record(v.record).sinkage_plastic = flow;
  s.vertices = {v};
  s.contacts = {0};
  s.contact_patch = {0};
  s.patch_start = {0, 1};
  s.patch_members = {0};
  s.patch_oob = {1.0};
  VertexLoad l;
  l.loaded = true;
  s.loads = {l};
  return s;
}

TEST(ScmBulldozer, SpreadsTheFlowOverTheRimAndConservesItWhileEroding) {
  GridParams g;
  g.spacing_m = 0.05;
  const double flow = 0.02;
  BulldozingParams p;
  p.enabled = true;
  p.flow_factor = 1.0;
  p.iterations = 0;  // rim only: each of the 4 neighbours gets a quarter
  {
    VertexGrid grid(g, nullptr);
    const ContactPatches s = one_vertex_patch(grid, flow);
    EXPECT_EQ(Bulldozer(p).run(grid, s), 4u);
    for (int n = 0; n < 4; ++n) {
      EXPECT_DOUBLE_EQ(grid.level_of(kNeighbourDi[n], kNeighbourDj[n]), flow / 4) << n;
    }
    EXPECT_EQ(grid.level_of(1, 1), 0.0);
  }
  // With erosion the 5 mm steps exceed delta tan(2 deg) = 1.7 mm: material moves outwards and
  // the total stays.
  p.iterations = 50;
  p.propagations = 3;
  p.erosion_angle_deg = 2.0;
  VertexGrid grid(g, nullptr);
  const ContactPatches s = one_vertex_patch(grid, flow);
  const std::size_t domain = Bulldozer(p).run(grid, s);
  EXPECT_EQ(domain, 4u + 8u + 12u + 16u);  // the rim and three rings
  double raised = 0.0;
  for (const VertexRecord& r : grid.records()) {
    if (r.i == 0 && r.j == 0) continue;
    raised += r.level_initial;
    EXPECT_EQ(r.level, r.level_initial);  // moved material shifts both together
  }
  EXPECT_NEAR(raised, flow, 1e-15);
  EXPECT_LT(grid.level_of(1, 0), flow / 4);  // the rim gave some away
  EXPECT_GT(grid.level_of(2, 0), 0.0);       // to the first ring
}

TEST(ScmReplication, MergeOrderIsTotalAndArrivalIndependent) {
  VertexChange low, high;
  low.level_m = -0.1;
  high.level_m = 0.0;
  EXPECT_TRUE(beats(low, 5, high, 1));
  EXPECT_FALSE(beats(high, 1, low, 5));
  VertexChange deeper = high;
  deeper.sinkage_plastic_m = 0.02;
  EXPECT_TRUE(beats(deeper, 9, high, 0));  // same level: larger plastic sinkage
  EXPECT_TRUE(beats(high, 0, high, 1));    // identical records: lower source id
  EXPECT_FALSE(beats(high, 1, high, 0));

  // Two remote lists applied in either order leave the same grid.
  GridParams g;
  g.spacing_m = 0.1;
  auto run = [&](bool swap) {
    VertexGrid grid(g, nullptr);
    Replication rep;
    rep.take_local_changes(grid);
    VertexChange a = low, b = deeper;
    a.i = b.i = 2;
    a.j = b.j = 3;
    std::vector<VertexChange> la{a}, lb{b};
    rep.apply_remote_changes(grid, 1, swap ? lb : la);
    rep.apply_remote_changes(grid, 2, swap ? la : lb);
    EXPECT_EQ(grid.level_of(2, 3), low.level_m);  // the lower level wins
    return Replication::grid_hash(grid);
  };
  EXPECT_EQ(run(false), run(true));
}
