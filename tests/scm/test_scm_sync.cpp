// Determinism (thread counts, repeated runs) and the deformation sync contract: copies of the
// terrain that exchange change lists hold bit-identical grids at every frame boundary, whatever
// the order in which the lists arrive, including when two vehicles touch one vertex in a frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <numbers>

#include "core/error.hpp"
#include "scm_test_util.hpp"

using namespace syndds;
using namespace syndds::scm;
using namespace syndds::scm::test;

namespace {


/// A wheel pressed kinematically 30 mm below the undeformed surface, rolling at v with slip.
terrain::WheelBodyState kinematic_wheel(Vec3 start, Vec3 direction, double v, double slip,
                                        double t) {
  terrain::WheelBodyState w;
  const double yaw = std::atan2(direction.y(), direction.x());
  w.pose.orientation = quat_from_yaw(yaw);
  w.pose.position = start + v * t * direction;
  w.pose.position.z() = kHmmwvWheelRadius - 0.03;
  w.linear_velocity = v * direction;
  const Vec3 axis = w.pose.orientation * Vec3::UnitY();
  // Driven: spins faster than it rolls.
  w.angular_velocity = axis * (v * (1.0 + slip) / kHmmwvWheelRadius);
  w.radius_m = kHmmwvWheelRadius;
  w.width_m = kHmmwvWheelWidth;
  return w;
}

/// Four wheels of a vehicle-sized rig, each carrying 6 kN on its own vertical degree of freedom,
/// driven with 20 % slip. Returns every load component of every step (for bit comparisons).
std::vector<double> drive_four_wheels(ScmTerrain& terrain, int steps) {
  const double dt = 2e-3, v = 2.0, w = 6000.0;
  std::vector<VerticalRig> rigs(4);
  const double xs[2] = {1.7, -1.7}, ys[2] = {0.9, -0.9};
  for (int k = 0; k < 4; ++k) {
    auto& rig = rigs[static_cast<std::size_t>(k)];
    rig.body.shape = CylinderShape{kHmmwvWheelRadius, kHmmwvWheelWidth};
    rig.body.pose.position = Vec3(xs[k / 2] - 3.0, ys[k % 2], kHmmwvWheelRadius);
    rig.body.linear_velocity = Vec3(v, 0, 0);
    rig.body.angular_velocity = Vec3(0, 1.2 * v / kHmmwvWheelRadius, 0);
    rig.mass_kg = 60.0;
    rig.damping_nspm = 3e4;
  }
  std::vector<double> trace;
  for (int n = 0; n < steps; ++n) {
    for (auto& rig : rigs) rig.step(terrain, w, dt);
    for (const auto& rig : rigs) {
      for (int c = 0; c < 3; ++c) {
        trace.push_back(rig.last.force[c]);
        trace.push_back(rig.last.torque[c]);
      }
      trace.push_back(rig.last.sinkage_m);
    }
  }
  return trace;
}

/// One frame of the crossing: in t1 a wheel drives east along y = 0, in t2 one north along
/// x = 0 (2 m/s, 20 % slip, 2 ms steps); they pass the origin in the same frames.
void drive_crossing_frame(ScmTerrain& t1, ScmTerrain& t2, int steps, double& t) {
  const double dt = 2e-3, v = 2.0;
  for (int s = 0; s < steps; ++s) {
    const auto w1 = kinematic_wheel(Vec3(-1.0, 0.0, 0.0), Vec3::UnitX(), v, 0.2, t);
    const auto w2 = kinematic_wheel(Vec3(0.0, -1.0, 0.0), Vec3::UnitY(), v, 0.2, t);
    terrain::WheelLoad l;
    t1.compute_wheel_loads(std::span(&w1, 1), dt, std::span(&l, 1));
    t2.compute_wheel_loads(std::span(&w2, 1), dt, std::span(&l, 1));
    t += dt;
  }
}

ScmParams sync_params(int threads = 1) {
  ScmParams p = params("mid", 0.05, 6.0, threads);
  p.bulldozing.enabled = true;
  return p;
}

}  // namespace

TEST(ScmDeterminism, ThreadCountDoesNotChangeResults) {
  std::vector<double> traces[3];
  std::uint64_t hashes[3] = {};
  for (int threads = 1; threads <= 3; ++threads) {
    ScmParams p = sync_params(threads);
    p.grid.spacing_m = 0.025;
    p.thread_min_vertices = 1;  // always split the work, even when small
    ScmTerrain terrain(p);
    traces[threads - 1] = drive_four_wheels(terrain, 250);
    hashes[threads - 1] = terrain.grid_hash();
    EXPECT_GT(terrain.stored_vertices(), 1000u);
  }
  EXPECT_TRUE(bit_equal(traces[0], traces[1]));
  EXPECT_TRUE(bit_equal(traces[0], traces[2]));
  EXPECT_EQ(hashes[0], hashes[1]);
  EXPECT_EQ(hashes[0], hashes[2]);
}

TEST(ScmDeterminism, RepeatedRunsAreIdentical) {
  ScmTerrain a(sync_params()), b(sync_params());
  const auto ta = drive_four_wheels(a, 200);
  const auto tb = drive_four_wheels(b, 200);
  EXPECT_TRUE(bit_equal(ta, tb));
  EXPECT_EQ(a.grid_hash(), b.grid_hash());
  // A different path gives a different hash: the hash sees the state.
  ScmTerrain c(sync_params());
  drive_four_wheels(c, 150);
  EXPECT_NE(a.grid_hash(), c.grid_hash());
}

TEST(ScmSync, CopiesExchangingChangesStayIdenticalWithConflicts) {
  // Process 1 drives a wheel east along y = 0, process 2 a wheel north along x = 0; they cross
  // the origin in the same frames. Processes 3 and 4 only receive, in opposite orders.
  ScmTerrain t1(sync_params()), t2(sync_params()), t3(sync_params()), t4(sync_params());
  t1.set_source_id(1);
  t2.set_source_id(2);
  t3.set_source_id(3);
  t4.set_source_id(4);
  const int steps_per_frame = 5;
  int conflicts = 0, differing_conflicts = 0;
  double t = 0.0;
  for (int frame = 0; frame < 100; ++frame) {
    drive_crossing_frame(t1, t2, steps_per_frame, t);
    const auto c1 = t1.take_local_changes();
    const auto c2 = t2.take_local_changes();
    EXPECT_TRUE(t3.take_local_changes().empty());
    EXPECT_TRUE(t4.take_local_changes().empty());
    // Same-vertex records of this frame.
    std::map<std::pair<int, int>, VertexChange> by_ij;
    for (const auto& c : c1) by_ij[{c.i, c.j}] = c;
    for (const auto& c : c2) {
      auto it = by_ij.find({c.i, c.j});
      if (it == by_ij.end()) continue;
      ++conflicts;
      if (!(it->second == c)) ++differing_conflicts;
    }
    t1.apply_remote_changes(2, c2);
    t2.apply_remote_changes(1, c1);
    t3.apply_remote_changes(1, c1);
    t3.apply_remote_changes(2, c2);
    t4.apply_remote_changes(2, c2);
    t4.apply_remote_changes(1, c1);
    const std::uint64_t h = t1.grid_hash();
    ASSERT_EQ(t2.grid_hash(), h) << "frame " << frame;
    ASSERT_EQ(t3.grid_hash(), h) << "frame " << frame;
    ASSERT_EQ(t4.grid_hash(), h) << "frame " << frame;
  }
  // The scenario really exercised the conflict rule.
  EXPECT_GT(conflicts, 10);
  EXPECT_GT(differing_conflicts, 10);
  EXPECT_GT(t1.stored_vertices(), 500u);
}

// A late joiner starts from the first vehicle's snapshot taken after its own changes of frame
// f (VehicleAgent::publish_soil), then merges every list of frame f, that vehicle's own list
// included, and goes on with the lists of later frames: it must hold what the writers hold,
// also where both wheels changed a vertex in frame f (the snapshot already has the first
// writer's record there; the second writer's may beat it). Joiners start in every fifth frame,
// merging a frame's lists in either order.
TEST(ScmSync, ALateJoinerFromASnapshotMidConflictFollowsTheWriters) {
  ScmTerrain t1(sync_params()), t2(sync_params());
  t1.set_source_id(1);
  t2.set_source_id(2);
  std::vector<std::unique_ptr<ScmTerrain>> joiners;
  std::vector<int> conflicts_at_start;
  double t = 0.0;
  for (int frame = 0; frame < 100; ++frame) {
    drive_crossing_frame(t1, t2, 5, t);
    const auto c1 = t1.take_local_changes();
    const auto c2 = t2.take_local_changes();
    if (frame % 5 == 0) {  // admitted now: the snapshot of t1 as publish_soil makes it
      const ScmSnapshot snap = t1.snapshot();
      for (int order = 0; order < 2; ++order) {
        auto j = std::make_unique<ScmTerrain>(sync_params());
        j->set_source_id(static_cast<std::uint32_t>(10 + joiners.size()));
        j->load_snapshot(snap);
        joiners.push_back(std::move(j));
      }
      std::set<std::pair<int, int>> in1;
      for (const auto& c : c1) in1.insert({c.i, c.j});
      int n = 0;
      for (const auto& c : c2) n += in1.count({c.i, c.j}) != 0 ? 1 : 0;
      conflicts_at_start.push_back(n);
    }
    t1.apply_remote_changes(2, c2);
    t2.apply_remote_changes(1, c1);
    for (std::size_t k = 0; k < joiners.size(); ++k) {
      auto& j = *joiners[k];  // as SensorAgent: merge the lists, then open the next window
      if (k % 2 == 0) {
        j.apply_remote_changes(1, c1);
        j.apply_remote_changes(2, c2);
      } else {
        j.apply_remote_changes(2, c2);
        j.apply_remote_changes(1, c1);
      }
      EXPECT_TRUE(j.take_local_changes().empty());
    }
    const std::uint64_t h = t1.grid_hash();
    ASSERT_EQ(t2.grid_hash(), h) << "frame " << frame;
    for (std::size_t k = 0; k < joiners.size(); ++k) {
      ASSERT_EQ(joiners[k]->grid_hash(), h)
          << "frame " << frame << ", joiner admitted in frame " << 5 * (k / 2);
    }
  }
  // Some joiners really started in a frame where both wheels changed the same vertices.
  EXPECT_GT(*std::max_element(conflicts_at_start.begin(), conflicts_at_start.end()), 0);
}

// Interest management: a copy that holds the records outside its interest box aside (per tile,
// resolved by the same conflict rule) and merges them when the box moves over them, or at the
// end, ends bit-identical to a copy that merged everything at once, with the same level bound
// (it decides which bodies may touch the soil). The two wheels cross, so the deferred slots see
// same-frame conflicts between sources.
TEST(ScmSync, DeferredRecordsMergeToTheSameGridAsAFullMerge) {
  ScmTerrain t1(sync_params()), t2(sync_params()), full(sync_params()), lazy(sync_params());
  t1.set_source_id(1);
  t2.set_source_id(2);
  full.set_source_id(3);
  lazy.set_source_id(4);
  double t = 0.0;
  std::size_t most_deferred = 0;
  for (int frame = 0; frame < 100; ++frame) {
    drive_crossing_frame(t1, t2, 5, t);
    const auto c1 = t1.take_local_changes();
    const auto c2 = t2.take_local_changes();
    full.take_local_changes();
    lazy.take_local_changes();
    // The lazy copy looks far away, then at a small box on the crossing (merging the tiles it
    // meets), then far away again.
    if (frame < 40 || frame >= 70) {
      lazy.set_interest_region(50.0, 50.0, 5.0);
    } else {
      lazy.set_interest_region(0.3, 0.3, 0.2);
    }
    // Opposite orders: the conflict rule, not the arrival order, must decide.
    full.apply_remote_changes(2, c2);
    full.apply_remote_changes(1, c1);
    lazy.apply_remote_changes(1, c1);
    lazy.apply_remote_changes(2, c2);
    most_deferred = std::max(most_deferred, lazy.deferred_vertices());
    if (frame >= 40 && frame < 70) {
      // Inside the current box the copies agree vertex for vertex.
      for (int i = 2; i <= 10; ++i) {
        for (int j = 2; j <= 10; ++j) {
          ASSERT_EQ(lazy.vertex(i, j), full.vertex(i, j)) << i << "," << j;
        }
      }
    }
  }
  EXPECT_GT(most_deferred, 500u);
  EXPECT_GT(lazy.deferred_vertices(), 0u);
  EXPECT_THROW(lazy.grid_hash(), std::logic_error);
  lazy.flush_deferred();
  EXPECT_EQ(lazy.deferred_vertices(), 0u);
  EXPECT_EQ(lazy.grid_hash(), full.grid_hash());
  EXPECT_EQ(lazy.stored_vertices(), full.stored_vertices());
  // The bound takes in deferred records when they are merged, not on arrival: it never exceeds
  // the full merge's, and loads do not depend on it (next test).
  EXPECT_LE(lazy.level_bound(), full.level_bound());
}

// A load depends on the soil under the bodies only, not on the highest soil anywhere (the level
// bound culls bodies and vertices). Two plates side by side over flat soil, one pressed 20 mm in,
// the other hovering 50 mm above it (within the 0.1 m patch test height, so its footprint joins
// the pressed plate's contact patch and changes its 1/b); one copy of the soil also holds a
// 0.5 m mound 4 m away, which raises its bound above the hovering plate. (Before the bound was
// given the patch test's margin where it culls bodies, the flat copy left the hovering plate
// out and the pressed plate's load differed.)
TEST(ScmSync, LoadsDoNotDependOnSoilAwayFromTheBodies) {
  ScmParams p = params("hard", 0.05, 6.0);  // k_c > 0: the load depends on the patch's 1/b
  ASSERT_GT(p.soil.bekker_kc, 0.0);
  ASSERT_EQ(p.patch_test_height_m, 0.1);
  ScmTerrain flat(p), mound(p);
  std::vector<VertexChange> far;
  for (int i = 80; i < 84; ++i) far.push_back({i, 0, 0.5, 0.5, 0.0, 0.0});
  mound.apply_remote_changes(7, far);
  ASSERT_EQ(flat.level_bound(), 0.0);
  ASSERT_EQ(mound.level_bound(), 0.5);
  std::vector<ContactBody> plates(2);
  for (int k = 0; k < 2; ++k) {
    plates[k].shape = BoxShape{Vec3(0.2, 0.2, 0.05)};
    plates[k].pose.position = Vec3(0.4 * k, 0.0, k == 0 ? 0.05 - 0.02 : 0.05 + 0.05);
  }
  auto loads = [&](ScmTerrain& t) {
    std::vector<terrain::WheelLoad> l(2);
    std::vector<double> trace;
    for (int n = 0; n < 3; ++n) {
      t.compute_body_loads(plates, 2e-3, l);
      for (const auto& w : l) {
        for (int c = 0; c < 3; ++c) trace.insert(trace.end(), {w.force[c], w.torque[c]});
      }
    }
    return trace;
  };
  const auto a = loads(flat), b = loads(mound);
  ASSERT_GT(a[4], 1000.0);  // the pressed plate carries a load (force z of the first step)
  EXPECT_TRUE(bit_equal(a, b));
  EXPECT_EQ(flat.last_step_stats().patches, mound.last_step_stats().patches);
}

// Soil routing on two crossing wheels: a routed copy receives only the records inside its box
// of tiles and, when the box grows, the full copy's state of the tiles it gained (as the full
// copy was before the frame's lists: the recorder's state of the previous frame). Its box starts
// far from the crossing, moves onto it a tile row at a time, then away again; inside its
// interest square it agrees with the full merge vertex for vertex, and after it came back over
// the crossing its copy there equals the full one.
TEST(ScmSync, ARoutedCopyEqualsAFullMergeInsideItsBox) {
  ScmTerrain t1(sync_params()), t2(sync_params()), full(sync_params()), routed(sync_params());
  t1.set_source_id(1);
  t2.set_source_id(2);
  full.set_source_id(3);
  routed.set_source_id(4);
  using Box = Replication::IndexBox;
  auto tiles = [](const Box& v) { return Replication::tiles_of(v); };
  Box box{0, -1, 0, -1};
  double t = 0.0;
  std::size_t loaded = 0;
  for (int frame = 0; frame < 120; ++frame) {
    drive_crossing_frame(t1, t2, 5, t);
    const auto c1 = t1.take_local_changes();
    const auto c2 = t2.take_local_changes();
    full.take_local_changes();
    routed.take_local_changes();
    // The interest square walks from x = 4.5 m down to the crossing and back; the box covers it
    // with one tile (1.6 m) to spare.
    const double x = frame < 60 ? 4.5 - 0.07 * frame : 0.3 + 0.07 * (frame - 60);
    const Box square = routed.interest_box(x, 0.0, 0.5);
    const Box need = tiles(routed.interest_box(x, 0.0, 0.5 + 1.6));
    if (frame > 0 && !(need.i_lo >= box.i_lo && need.i_hi <= box.i_hi && need.j_lo >= box.j_lo &&
                       need.j_hi <= box.j_hi)) {
      const Box now = tiles(routed.interest_box(x, 0.0, 0.5 + 3.2));
      const auto state = full.added_tiles_state(now, box);
      loaded += state.size();
      routed.load_added_tiles(now, box, state);
      routed.drop_tiles_outside(now);
      box = now;
    } else if (frame == 0) {
      box = tiles(routed.interest_box(x, 0.0, 0.5 + 3.2));
    }
    routed.set_interest_region(x, 0.0, 0.5);
    full.apply_remote_changes(1, c1);
    full.apply_remote_changes(2, c2);
    for (const auto* c : {&c1, &c2}) {
      std::vector<VertexChange> in_box;
      for (const auto& v : *c) {
        if (Replication::contains(box, v.i >> Replication::kTileShift,
                                  v.j >> Replication::kTileShift)) {
          in_box.push_back(v);
        }
      }
      routed.apply_remote_changes(c == &c1 ? 1 : 2, in_box);
    }
    for (int i = square.i_lo; i <= square.i_hi; ++i) {
      for (int j = square.j_lo; j <= square.j_hi; ++j) {
        ASSERT_EQ(routed.vertex(i, j), full.vertex(i, j)) << "frame " << frame << " " << i << ","
                                                          << j;
      }
    }
  }
  EXPECT_GT(loaded, 200u);  // the box gained tiles the wheels had deformed
  // A record outside the tiles a box gains is refused; so is a gained tile inside the square.
  const Box far{20, 21, 20, 21};
  EXPECT_THROW(routed.load_added_tiles(far, box, std::vector<VertexChange>{{0, 0, 0, 0, 0, 0}}),
               ProtocolError);
  EXPECT_THROW(routed.load_added_tiles(tiles(routed.interest_box(0.0, 0.0, 10.0)), Box{0, -1, 0, -1},
                                       {}),
               std::logic_error);
}

// The slot rule on hand-made records of one far vertex: within a frame the conflict rule picks
// the winner whatever the arrival order; a later frame's record replaces an earlier one even
// when the earlier one would have won a conflict.
TEST(ScmSync, DeferredSlotsFollowTheConflictRuleAndFrameOrder) {
  auto record = [](double level) {
    VertexChange c;
    c.i = 100;
    c.j = 100;
    c.level_m = level;
    c.level_initial_m = 0.0;
    c.sinkage_plastic_m = -level;
    c.sigma_yield_pa = 1e4;
    return c;
  };
  const VertexChange deep = record(-0.2), shallow = record(-0.1), later = record(-0.05);
  for (bool deep_first : {true, false}) {
    ScmTerrain lazy(sync_params());
    lazy.take_local_changes();
    lazy.set_interest_region(-5.0, -5.0, 0.5);  // far from vertex (100, 100) = (5 m, 5 m)
    lazy.apply_remote_changes(deep_first ? 1 : 2, std::vector{deep_first ? deep : shallow});
    lazy.apply_remote_changes(deep_first ? 2 : 1, std::vector{deep_first ? shallow : deep});
    ASSERT_EQ(lazy.deferred_vertices(), 1u);
    EXPECT_FALSE(lazy.vertex(100, 100).has_value());  // not merged yet
    lazy.flush_deferred();
    EXPECT_EQ(lazy.vertex(100, 100), deep) << deep_first;

    lazy.take_local_changes();  // frame 1: the deep record, then frame 2: a shallower one
    lazy.apply_remote_changes(1, std::vector{deep});
    lazy.take_local_changes();
    lazy.apply_remote_changes(2, std::vector{later});
    lazy.set_interest_region(5.0, 5.0, 0.5);  // the vehicle arrives: merged now
    EXPECT_EQ(lazy.deferred_vertices(), 0u);
    EXPECT_EQ(lazy.vertex(100, 100), later) << deep_first;
  }
}

// Many deferred tiles (every far rut) and a small box: the box's own tiles are looked up, and
// exactly the tiles it meets are merged, whichever of its corners a tile holds.
TEST(ScmSync, ASmallBoxOverManyDeferredTilesMergesExactlyTheTilesItMeets) {
  constexpr std::int32_t kTile = Replication::kTileSize;
  ScmTerrain lazy(sync_params()), full(sync_params());
  lazy.take_local_changes();
  full.take_local_changes();
  lazy.set_interest_region(100.0, 100.0, 0.5);  // outside the area: everything is deferred
  std::vector<VertexChange> records;
  for (std::int32_t ti = -3; ti <= 3; ++ti) {
    for (std::int32_t tj = -3; tj <= 3; ++tj) {
      records.push_back({ti * kTile + 5, tj * kTile + 5, -0.02, 0.0, 0.02, 1e4});
    }
  }
  lazy.apply_remote_changes(1, records);
  full.apply_remote_changes(1, records);
  ASSERT_EQ(lazy.deferred_vertices(), 49u);
  const double d = sync_params().grid.spacing_m;
  auto merged = [&](std::int32_t ti, std::int32_t tj) {
    return lazy.vertex(ti * kTile + 5, tj * kTile + 5).has_value();
  };
  // Inside tile (1, 2) only.
  lazy.set_interest_region((kTile + 16) * d, (2 * kTile + 16) * d, 0.3);
  EXPECT_EQ(lazy.deferred_vertices(), 48u);
  EXPECT_TRUE(merged(1, 2));
  EXPECT_FALSE(merged(2, 2));
  EXPECT_FALSE(merged(1, 1));
  // Over the corner shared by tiles (1, 1), (1, 2), (2, 1) and (2, 2).
  lazy.set_interest_region(2 * kTile * d, 2 * kTile * d, 0.3);
  EXPECT_EQ(lazy.deferred_vertices(), 45u);
  for (auto [ti, tj] : {std::pair{1, 1}, {2, 1}, {2, 2}}) EXPECT_TRUE(merged(ti, tj));
  EXPECT_FALSE(merged(0, 0));
  EXPECT_FALSE(merged(3, 3));
  lazy.flush_deferred();
  EXPECT_EQ(lazy.deferred_vertices(), 0u);
  EXPECT_EQ(lazy.grid_hash(), full.grid_hash());
}

TEST(ScmSync, ConflictRuleKeepsTheDeeperRecordInAnyOrder) {
  ScmParams p = sync_params();
  ScmTerrain own(p), other(p);
  own.set_source_id(5);
  VertexChange mine{3, 4, -0.02, 0.0, 0.019, 1e4};
  VertexChange deeper{3, 4, -0.03, 0.0, 0.028, 2e4};
  VertexChange shallower{3, 4, -0.01, 0.0, 0.009, 5e3};
  // A frame's merge window opens with take_local_changes(); `mine` stands for this process's own
  // record of the frame (the first claim of the window).
  (void)own.take_local_changes();
  own.apply_remote_changes(5, std::span(&mine, 1));
  own.apply_remote_changes(7, std::span(&shallower, 1));
  EXPECT_EQ(*own.vertex(3, 4), mine);
  own.apply_remote_changes(6, std::span(&deeper, 1));
  EXPECT_EQ(*own.vertex(3, 4), deeper);
  // Reverse order on another copy, same result.
  (void)other.take_local_changes();
  other.apply_remote_changes(6, std::span(&deeper, 1));
  other.apply_remote_changes(7, std::span(&shallower, 1));
  other.apply_remote_changes(5, std::span(&mine, 1));
  EXPECT_EQ(*other.vertex(3, 4), deeper);
  // The next frame starts a new window: a shallower record replaces the old one outright.
  (void)other.take_local_changes();
  other.apply_remote_changes(7, std::span(&shallower, 1));
  EXPECT_EQ(*other.vertex(3, 4), shallower);
}

TEST(ScmSync, LocalChangesAreSortedAndTakenOnce) {
  ScmTerrain t(sync_params());
  const auto w = kinematic_wheel(Vec3::Zero(), Vec3::UnitX(), 1.0, 0.0, 0.0);
  terrain::WheelLoad l;
  t.compute_wheel_loads(std::span(&w, 1), 2e-3, std::span(&l, 1));
  const auto changes = t.take_local_changes();
  ASSERT_FALSE(changes.empty());
  EXPECT_EQ(changes.size(), t.stored_vertices());
  EXPECT_TRUE(std::is_sorted(changes.begin(), changes.end(), [](const auto& a, const auto& b) {
    return a.i != b.i ? a.i < b.i : a.j < b.j;
  }));
  EXPECT_TRUE(t.take_local_changes().empty());
  EXPECT_GT(l.force.z(), 0.0);
}

TEST(ScmSync, RejectsChangesOutsideTheArea) {
  ScmTerrain t(sync_params());
  VertexChange bad{100000, 0, 0.0, 0.0, 0.0, 0.0};
  EXPECT_THROW(t.apply_remote_changes(1, std::span(&bad, 1)), ProtocolError);
}

TEST(ScmSync, SnapshotRoundTripLetsALateJoinerFollow) {
  ScmTerrain a(sync_params()), late(sync_params());
  a.set_source_id(1);
  late.set_source_id(9);
  const double dt = 2e-3;
  double t = 0.0;
  auto frame = [&](ScmTerrain& terrain) {
    for (int s = 0; s < 5; ++s) {
      const auto w = kinematic_wheel(Vec3(-2.0, 0.3, 0.0), Vec3(1, 1, 0).normalized(), 2.0, 0.1, t);
      terrain::WheelLoad l;
      terrain.compute_wheel_loads(std::span(&w, 1), dt, std::span(&l, 1));
      t += dt;
    }
    return terrain.take_local_changes();
  };
  for (int k = 0; k < 40; ++k) frame(a);
  const ScmSnapshot snap = a.snapshot();
  EXPECT_EQ(snap.vertices.size(), a.stored_vertices());
  late.load_snapshot(snap);
  EXPECT_EQ(late.grid_hash(), a.grid_hash());
  EXPECT_EQ(late.snapshot().vertices, snap.vertices);
  for (int k = 0; k < 40; ++k) {
    const auto changes = frame(a);
    (void)late.take_local_changes();
    late.apply_remote_changes(1, changes);
    ASSERT_EQ(late.grid_hash(), a.grid_hash()) << "frame " << k;
  }
  // Surface queries agree too.
  EXPECT_EQ(late.height(0.5, 0.8), a.height(0.5, 0.8));
  ScmParams other = sync_params();
  other.grid.spacing_m = 0.1;
  ScmTerrain wrong(other);
  EXPECT_THROW(wrong.load_snapshot(snap), std::invalid_argument);
}

TEST(ScmSurface, HeightFollowsTheRutAndNormalTheSlope) {
  ScmTerrain t(sync_params());
  EXPECT_EQ(t.height(0.3, 0.2), 0.0);
  EXPECT_EQ(t.normal(0.3, 0.2), Vec3::UnitZ());
  EXPECT_NEAR(t.friction(0, 0), std::tan(deg_to_rad(30.0)), 1e-12);
  const auto w = kinematic_wheel(Vec3::Zero(), Vec3::UnitX(), 1.0, 0.0, 0.0);
  terrain::WheelLoad l;
  t.compute_wheel_loads(std::span(&w, 1), 2e-3, std::span(&l, 1));
  // The vertex under the wheel centre went down to the wheel's bottom.
  EXPECT_NEAR(t.vertex_height(0, 0), -0.03, 1e-12);
  EXPECT_NEAR(t.height(0.0, 0.0), -0.03, 1e-12);
  // Bilinear between vertices.
  const double h = t.height(0.025, 0.0);
  EXPECT_NEAR(h, 0.5 * (t.vertex_height(0, 0) + t.vertex_height(1, 0)), 1e-12);
  // At the rut's north wall (rut below y = 0.127, undeformed from y = 0.15) the surface rises
  // to the north, so the normal leans south, into the rut.
  const Vec3 n = t.normal(0.0, 0.1499);
  EXPECT_GT(n.z(), 0.0);
  EXPECT_LT(n.y(), -0.1) << n.transpose();
}

TEST(ScmContact, WheelOrientationIsHonoured) {
  // The same wheel rolling east (yaw 0) and north (yaw 90 deg) on a square grid must give the
  // same loads, rotated; a wheel with its axis turned along the travel direction must not.
  auto run = [](Vec3 dir, double yaw_offset) {
    ScmTerrain t(sync_params());
    terrain::WheelBodyState w = kinematic_wheel(Vec3::Zero(), dir, 1.0, 0.2, 0.0);
    w.pose.orientation = w.pose.orientation * quat_from_yaw(yaw_offset);
    terrain::WheelLoad l;
    for (int k = 0; k < 20; ++k) {
      t.compute_wheel_loads(std::span(&w, 1), 2e-3, std::span(&l, 1));
      w.pose.position += 2e-3 * w.linear_velocity;
    }
    return std::make_pair(l, t.last_step_stats().contact_vertices);
  };
  const auto [east, ne] = run(Vec3::UnitX(), 0.0);
  const auto [north, nn] = run(Vec3::UnitY(), 0.0);
  EXPECT_EQ(ne, nn);
  EXPECT_NEAR(north.force.z(), east.force.z(), 1e-6 * east.force.z());
  EXPECT_NEAR(north.force.y(), east.force.x(), 1e-6 * std::abs(east.force.x()));
  EXPECT_NEAR(north.sinkage_m, east.sinkage_m, 1e-9);
  EXPECT_GT(east.force.x(), 0.0);  // driven 20 % faster than it rolls: traction forward
  const auto [across, na] = run(Vec3::UnitX(), std::numbers::pi / 2);
  EXPECT_NE(na, ne);  // a cylinder lying along the travel has another footprint
}

TEST(ScmContact, WheelAndBodyInterfacesAgree) {
  ScmTerrain a(sync_params()), b(sync_params());
  const auto w = kinematic_wheel(Vec3(0.2, 0.1, 0), Vec3(1, 0.3, 0).normalized(), 1.5, 0.1, 0.0);
  ContactBody body;
  body.pose = w.pose;
  body.linear_velocity = w.linear_velocity;
  body.angular_velocity = w.angular_velocity;
  body.shape = CylinderShape{w.radius_m, w.width_m};
  terrain::WheelLoad la, lb;
  a.compute_wheel_loads(std::span(&w, 1), 2e-3, std::span(&la, 1));
  b.compute_body_loads(std::span(&body, 1), 2e-3, std::span(&lb, 1));
  EXPECT_EQ(la.force, lb.force);
  EXPECT_EQ(la.torque, lb.torque);
  EXPECT_EQ(a.grid_hash(), b.grid_hash());
  // Size mismatch and bad dt are programming errors.
  terrain::WheelLoad two[2];
  EXPECT_THROW(a.compute_wheel_loads(std::span(&w, 1), 2e-3, std::span(two, 2)),
               std::invalid_argument);
  EXPECT_THROW(a.compute_wheel_loads(std::span(&w, 1), 0.0, std::span(&la, 1)),
               std::invalid_argument);
}

TEST(ScmBulldozing, RimGainsWhatTheRutLoses) {
  for (double flow : {1.0, 0.0}) {
    ScmParams p = sync_params();
    p.bulldozing.flow_factor = flow;
    ScmTerrain t(p);
    drive_four_wheels(t, 400);
    // Plastic volume pressed down in total: sum of sinkage_plastic over the ruts.
    double pressed = 0.0, highest = -1.0;
    for (const auto& v : t.snapshot().vertices) {
      pressed += v.sinkage_plastic_m * p.grid.spacing_m * p.grid.spacing_m;
      highest = std::max(highest, v.level_m);
    }
    ASSERT_GT(pressed, 0.01);
    const double change = t.plastic_volume_change_m3();
    if (flow == 1.0) {
      EXPECT_NEAR(change, 0.0, 1e-9 * pressed) << "pressed " << pressed;
      EXPECT_GT(highest, 0.005);  // rims stand above the undeformed surface
      // Erosion keeps the rims at most at the erosion slope where it acted (loosely: no spike
      // higher than a few cells of slope).
      EXPECT_LT(highest, 0.2);
    } else {
      EXPECT_NEAR(change, -pressed, 1e-9 * pressed);  // no flow: pure compaction
      EXPECT_LE(highest, 0.0);
    }
  }
}

namespace {
/// Undeformed ground rising 10 % to the east.
class Slope final : public terrain::TerrainSurface {
 public:
  double height(double x, double) const override { return 0.5 + 0.1 * x; }
  Vec3 normal(double, double) const override { return Vec3(-0.1, 0, 1).normalized(); }
  double friction(double, double) const override { return 0.8; }
};
}  // namespace

TEST(ScmSurface, BaseSurfaceGivesTheUndeformedHeight) {
  ScmParams p = params("mid", 0.05, 3.0);
  ScmTerrain t(p, std::make_shared<Slope>());
  EXPECT_NEAR(t.height(1.0, 0.3), 0.6, 1e-12);
  EXPECT_NEAR(t.normal(1.02, 0.3).x(), Vec3(-0.1, 0, 1).normalized().x(), 1e-9);
  // A wheel pressed 30 mm into the slope: sinkage is measured from the base surface there.
  terrain::WheelBodyState w = kinematic_wheel(Vec3(1.0, 0.0, 0.0), Vec3::UnitX(), 0.0, 0.0, 0.0);
  w.pose.position.z() = 0.6 + kHmmwvWheelRadius - 0.03;
  terrain::WheelLoad l;
  t.compute_wheel_loads(std::span(&w, 1), 2e-3, std::span(&l, 1));
  EXPECT_TRUE(l.in_contact);
  EXPECT_NEAR(l.sinkage_m, 0.03, 0.003);  // the lowest point meets the slope slightly off-centre
  EXPECT_NEAR(t.vertex_height(20, 0), 0.57, 1e-9);
  EXPECT_GT(l.force.z(), 0.0);
}

TEST(ScmSurface, NoSoilOutsideTheArea) {
  ScmParams p = params("mid", 0.05, 1.0);
  ScmTerrain t(p);
  EXPECT_FALSE(t.in_area(100, 0));
  terrain::WheelBodyState w = kinematic_wheel(Vec3(5.0, 0.0, 0.0), Vec3::UnitX(), 1.0, 0.0, 0.0);
  terrain::WheelLoad l;
  t.compute_wheel_loads(std::span(&w, 1), 2e-3, std::span(&l, 1));
  EXPECT_FALSE(l.in_contact);
  EXPECT_EQ(l.force, Vec3::Zero());
  EXPECT_EQ(t.stored_vertices(), 0u);
  EXPECT_EQ(t.height(5.0, 0.0), 0.0);  // the flat base height is still reported there
}
