// Checkpoints of the SCM soil: a copy saved at a frame boundary and loaded into a fresh terrain
// continues bit-identically to the copy that ran on (forces, grid hash, stats, saved bytes),
// including the merge window, deferred records of interest management and the soil law's
// contact state; the encoding is sparse; a state of another grid or soil is refused.
#include <gtest/gtest.h>

#include "../core/state_test_util.hpp"

#include <cstdio>
#include <cstring>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "core/state_io.hpp"
#include "scm_test_util.hpp"

using namespace syndds;
using namespace syndds::scm;
using namespace syndds::scm::test;

namespace {

constexpr int kStepsPerFrame = 5;

ScmParams state_params() {
  ScmParams p = params("mid", 0.05, 6.0);
  p.bulldozing.enabled = true;
  return p;
}

/// A wheel of process 2 pressed kinematically 30 mm into the soil, driving north along x = 0
/// with 20 % slip (crossing the ruts of process 1).
terrain::WheelBodyState crossing_wheel(double t) {
  terrain::WheelBodyState w;
  w.pose.orientation = quat_from_yaw(0.5 * std::numbers::pi);
  w.pose.position = Vec3(0.0, -1.5 + 2.0 * t, kHmmwvWheelRadius - 0.03);
  w.linear_velocity = Vec3(0.0, 2.0, 0.0);
  w.angular_velocity = (w.pose.orientation * Vec3::UnitY()) * (2.0 * 1.2 / kHmmwvWheelRadius);
  w.radius_m = kHmmwvWheelRadius;
  w.width_m = kHmmwvWheelWidth;
  return w;
}

/// Three processes' soil copies as the vehicle agent drives them, frame by frame: process 1
/// carries two wheels free to sink under 6 kN each (forces feed back into their positions),
/// process 2 one kinematic wheel, and a third copy only receives, merging within a small box
/// that follows wheel 2 (everything else is deferred). Each frame begins with the interest box
/// and the other processes' lists of the frame before, then the steps, then the own list.
struct World {
  ScmTerrain t1{state_params()}, t2{state_params()}, lazy{state_params()};
  std::vector<VerticalRig> rigs = std::vector<VerticalRig>(2);
  double t = 0.0;
  std::vector<VertexChange> c1, c2;  // last frame's lists, in flight
  int frame = 0;

  World() {
    t1.set_source_id(1);
    t2.set_source_id(2);
    lazy.set_source_id(3);
    for (std::size_t k = 0; k < rigs.size(); ++k) {
      VerticalRig& rig = rigs[k];
      rig.body.shape = CylinderShape{kHmmwvWheelRadius, kHmmwvWheelWidth};
      rig.body.pose.position = Vec3(-2.0, k == 0 ? 0.45 : -0.45, kHmmwvWheelRadius);
      rig.body.linear_velocity = Vec3(2.0, 0, 0);
      rig.body.angular_velocity = Vec3(0, 1.2 * 2.0 / kHmmwvWheelRadius, 0);
      rig.mass_kg = 60.0;
      rig.damping_nspm = 3e4;
    }
  }

  /// One frame; appends every force, torque and sinkage of it to `trace`.
  void run_frame(std::vector<double>& trace) {
    const Vec3 w2 = crossing_wheel(t).pose.position;
    lazy.set_interest_region(w2.x(), w2.y(), 0.6);
    t1.apply_remote_changes(2, c2);
    t2.apply_remote_changes(1, c1);
    lazy.apply_remote_changes(2, c2);
    lazy.apply_remote_changes(1, c1);
    for (int s = 0; s < kStepsPerFrame; ++s) {
      for (auto& rig : rigs) rig.step(t1, 6000.0, kStepS);
      const auto w = crossing_wheel(t);
      terrain::WheelLoad l;
      t2.compute_wheel_loads(std::span(&w, 1), kStepS, std::span(&l, 1));
      t += kStepS;
      for (const terrain::WheelLoad* load : {&rigs[0].last, &rigs[1].last, &l}) {
        for (int c = 0; c < 3; ++c) {
          trace.push_back(load->force[c]);
          trace.push_back(load->torque[c]);
        }
        trace.push_back(load->sinkage_m);
        trace.push_back(load->in_contact ? 1.0 : 0.0);
      }
    }
    c1 = t1.take_local_changes();
    c2 = t2.take_local_changes();
    lazy.take_local_changes();
    ++frame;
  }
};

std::string save(const ScmTerrain& terrain) {
  core::StateWriter w;
  terrain.save_state(w);
  return w.take();
}

void load(ScmTerrain& terrain, const std::string& bytes) {
  core::StateReader r(bytes, "soil.state");
  terrain.load_state(r);
  EXPECT_TRUE(r.at_end());
}

/// Normal stress of the last step at every vertex under load in it (sinking wheels of t1).
std::vector<double> pressures(const ScmTerrain& t) {
  std::vector<double> out;
  for (std::int32_t i = t.i_min(); i <= t.i_max(); ++i) {
    for (std::int32_t j = -15; j <= 15; ++j) {
      if (const double p = t.vertex_pressure(i, j); p != 0.0) out.push_back(p);
    }
  }
  return out;
}

void expect_same_stats(const ScmTerrain& a, const ScmTerrain& b, int frame) {
  const ScmStepStats& x = a.last_step_stats();
  const ScmStepStats& y = b.last_step_stats();
  EXPECT_EQ(x.footprint_vertices, y.footprint_vertices) << "frame " << frame;
  EXPECT_EQ(x.covered_vertices, y.covered_vertices) << "frame " << frame;
  EXPECT_EQ(x.contact_vertices, y.contact_vertices) << "frame " << frame;
  EXPECT_EQ(x.patches, y.patches) << "frame " << frame;
  EXPECT_EQ(x.patch_vertices, y.patch_vertices) << "frame " << frame;
  EXPECT_EQ(x.bulldozing_domain, y.bulldozing_domain) << "frame " << frame;
}

}  // namespace

TEST(ScmState, ACopyResumedFromACheckpointContinuesBitForBit) {
  World a;
  std::vector<double> ignored;
  for (int f = 0; f < 40; ++f) a.run_frame(ignored);
  // The checkpoint catches everything in flight: wheels in contact (shear state), an open merge
  // window with this frame's own claims, pending remote lists, deferred records.
  ASSERT_TRUE(a.rigs[0].last.in_contact);
  ASSERT_FALSE(a.c1.empty());
  ASSERT_FALSE(a.c2.empty());
  ASSERT_GT(a.lazy.deferred_vertices(), 100u);

  World b;
  load(b.t1, save(a.t1));
  load(b.t2, save(a.t2));
  load(b.lazy, save(a.lazy));
  b.rigs = a.rigs;  // the test's own rig and message state, as the agents would restore theirs
  b.t = a.t;
  b.c1 = a.c1;
  b.c2 = a.c2;
  b.frame = a.frame;
  EXPECT_EQ(save(b.t1), save(a.t1));
  EXPECT_EQ(save(b.lazy), save(a.lazy));
  expect_same_stats(a.t1, b.t1, a.frame);
  EXPECT_TRUE(bit_equal(pressures(a.t1), pressures(b.t1)));
  EXPECT_GT(pressures(a.t1).size(), 20u);

  std::vector<double> ta, tb;
  for (int f = 0; f < 60; ++f) {
    a.run_frame(ta);
    b.run_frame(tb);
    ASSERT_EQ(a.t1.grid_hash(), b.t1.grid_hash()) << "frame " << a.frame;
    ASSERT_EQ(a.t2.grid_hash(), b.t2.grid_hash()) << "frame " << a.frame;
    ASSERT_EQ(a.c1, b.c1) << "frame " << a.frame;
    ASSERT_EQ(a.c2, b.c2) << "frame " << a.frame;
    ASSERT_EQ(a.lazy.deferred_vertices(), b.lazy.deferred_vertices()) << "frame " << a.frame;
    ASSERT_EQ(a.t1.level_bound(), b.t1.level_bound());
    expect_same_stats(a.t1, b.t1, a.frame);
    expect_same_stats(a.t2, b.t2, a.frame);
  }
  EXPECT_TRUE(bit_equal(ta, tb));
  // Equal states write equal bytes, whatever order their vertices were inserted in.
  EXPECT_EQ(save(a.t1), save(b.t1));
  EXPECT_EQ(save(a.t2), save(b.t2));
  EXPECT_EQ(save(a.lazy), save(b.lazy));
  EXPECT_GT(a.lazy.deferred_vertices(), 0u);
  // With the lists in flight merged, the copy that deferred holds what the drivers hold.
  for (World* w : {&a, &b}) {
    w->t1.apply_remote_changes(2, w->c2);
    w->lazy.apply_remote_changes(1, w->c1);
    w->lazy.apply_remote_changes(2, w->c2);
    w->lazy.flush_deferred();
  }
  EXPECT_EQ(a.lazy.grid_hash(), b.lazy.grid_hash());
  EXPECT_EQ(a.lazy.grid_hash(), a.t1.grid_hash());
}

// Sparse: an untouched soil writes only its fingerprint and counters; a deformed one at most
// kMaxStateRecordBytes per stored vertex (i, j, flags, level and the fields that differ from a
// fresh record) plus 12 bytes per claim of the open merge window; a dense grid would be 40 bytes
// for each of its 58081 vertices.
TEST(ScmState, TheCheckpointIsSparse) {
  const std::string empty = save(ScmTerrain(state_params()));
  EXPECT_LT(empty.size(), 512u);

  World a;
  std::vector<double> ignored;
  for (int f = 0; f < 40; ++f) a.run_frame(ignored);
  const std::string bytes = save(a.t1);
  const std::size_t n = a.t1.stored_vertices();
  ASSERT_GT(n, 400u);
  EXPECT_LE(bytes.size(), empty.size() + n * VertexGrid::kMaxStateRecordBytes + a.c1.size() * 12);
  // Most vertices are rut or rim vertices out of contact: 25 to 33 bytes, not 73.
  EXPECT_LT(static_cast<double>(bytes.size() - empty.size()) / static_cast<double>(n), 40.0);
  const std::size_t dense = 241u * 241u * sizeof(VertexChange);
  EXPECT_LT(bytes.size() * 10, dense);
  std::printf("deformed soil: %zu stored vertices, %zu bytes (%.1f per vertex), untouched %zu\n",
              n, bytes.size(), static_cast<double>(bytes.size() - empty.size()) / n, empty.size());
}

TEST(ScmState, AStateOfAnotherGridOrSoilIsRefusedByName) {
  World a;
  std::vector<double> ignored;
  for (int f = 0; f < 5; ++f) a.run_frame(ignored);
  const std::string bytes = save(a.t1);
  {
    ScmParams p = state_params();
    p.grid.spacing_m = 0.1;
    ScmTerrain other(p);
    syndds::test::expect_state_error([&] { load(other, bytes); },
                       {"soil.state", "scm_terrain", "another grid or soil",
                        "grid spacing_m is 0.05 in the state and 0.1 in this terrain"});
  }
  {
    ScmParams p = state_params();
    p.grid.x_max_m = 8.0;
    ScmTerrain other(p);
    syndds::test::expect_state_error([&] { load(other, bytes); }, {"grid x_max_m is 6 in the state and 8"});
  }
  {
    ScmParams p = state_params();
    p.soil = preset("soft").soil;
    ScmTerrain other(p);
    syndds::test::expect_state_error([&] { load(other, bytes); }, {"soil bekker_kphi"});
  }
  {
    ScmParams p = state_params();
    p.bulldozing.enabled = false;
    ScmTerrain other(p);
    syndds::test::expect_state_error([&] { load(other, bytes); }, {"bulldozing enabled is 1 in the state and 0"});
  }
  {
    // Threads and the interest radius do not change results: such a state loads.
    ScmParams p = state_params();
    p.threads = 2;
    p.interest_radius_m = 3.0;
    ScmTerrain same(p);
    load(same, bytes);
    EXPECT_EQ(same.grid_hash(), a.t1.grid_hash());
  }
}

TEST(ScmState, ATruncatedOrDamagedStateIsRefused) {
  World a;
  std::vector<double> ignored;
  for (int f = 0; f < 5; ++f) a.run_frame(ignored);
  const std::string bytes = save(a.t1);
  {
    ScmTerrain t(state_params());
    syndds::test::expect_state_error([&] { load(t, bytes.substr(0, bytes.size() / 2)); },
                       {"soil.state", "section 'scm_terrain' claims"});
  }
  {
    // Another component's state where the soil's is expected.
    core::StateWriter w;
    w.begin("vehicle", 1);
    w.end();
    ScmTerrain t(state_params());
    syndds::test::expect_state_error([&] { load(t, w.bytes()); }, {"expected section 'scm_terrain', found 'vehicle'"});
  }
}

// Saved between steps, before the frame's list was taken: the changes still to publish are
// part of the state (at a frame boundary the agent has just taken them, so the list is empty).
TEST(ScmState, ChangesNotYetPublishedSurviveTheCheckpoint) {
  World a;
  std::vector<double> ignored;
  for (int f = 0; f < 10; ++f) a.run_frame(ignored);
  for (auto& rig : a.rigs) rig.step(a.t1, 6000.0, kStepS);
  ScmTerrain b(state_params());
  load(b, save(a.t1));
  const auto la = a.t1.take_local_changes();
  EXPECT_FALSE(la.empty());
  EXPECT_EQ(b.take_local_changes(), la);
}
