#pragma once
// Soil Contact Model (SCM) deformable terrain, after Chrono::Vehicle's SCMTerrain.
//
// A height grid of spacing delta over a rectangular area; only vertices that ever deformed are
// stored (hash index keyed by (i, j)). Each call of compute_body_loads (one dynamics step):
//   1. casts one vertical ray per grid vertex under each body's footprint against the body's
//      true shape (cylinder or box, any orientation) -> vertices in contact (ray hit below the
//      vertex's current level);
//   2. groups contact vertices into 4-connected patches (with the vertices the body is less than
//      the test height above, as Chrono does), b = 2 A / P per patch;
//   3. applies the per-vertex law: elastic trial Ke (s - s_plastic); above the yield stress
//      Bekker sigma = (kc / b + kphi) s^n, acting along the body's surface normal (per unit
//      horizontal area); damping -R v_n (vertical); Janosi-Hanamoto shear through a
//      mobilisation vector m that follows the horizontal slip path, tau = (c + sigma tan phi) m;
//      summed with torque about the body centre;
//   4. optionally bulldozes the plastically displaced volume to the rim of each patch.
// See docs/scm.md for the equations, the sync rule and the limits.
//
// ScmTerrain is a facade over the pieces: VertexGrid (storage), SoilLaw (the per-vertex law,
// constant parameters), contact_patch.hpp (geometry and patches of a step), Bulldozer
// (bulldozing.hpp) and Replication (sync and snapshots); compute_body_loads runs the steps.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <variant>
#include <vector>

#include "core/math.hpp"
#include "scm/replication.hpp"
#include "scm/scm_params.hpp"
#include "scm/soil_law.hpp"
#include "scm/vertex_grid.hpp"
#include "terrain/terrain.hpp"

namespace syndds {
class ThreadPool;
}

namespace syndds::scm {

/// Solid cylinder centred on the body origin, axis along the body's local y (a wheel).
struct CylinderShape {
  double radius_m = 0.0;
  double width_m = 0.0;
};
/// Solid box centred on the body origin, edges along the body's local axes (a plate).
struct BoxShape {
  Vec3 half_extents_m = Vec3::Zero();
};
using BodyShape = std::variant<CylinderShape, BoxShape>;

/// A rigid body in contact with the soil. Velocities in the world frame, of the body origin.
struct ContactBody {
  Pose pose;
  Vec3 linear_velocity = Vec3::Zero();
  Vec3 angular_velocity = Vec3::Zero();
  BodyShape shape;
};

/// Counters of the last compute_body_loads call (diagnostics and benchmarks).
struct ScmStepStats {
  std::size_t footprint_vertices = 0;  // vertices inside the bodies' footprint boxes
  std::size_t covered_vertices = 0;    // of those, under a body (vertical ray hits it)
  std::size_t contact_vertices = 0;    // of those, penetrated (body below the surface)
  std::size_t patches = 0;
  std::size_t patch_vertices = 0;     // vertices of the patches (contacts + test-height ring)
  std::size_t bulldozing_domain = 0;  // vertices in the erosion domain
};

class ScmTerrain final : public terrain::TerrainSurface, public terrain::WheelTerrainContact {
 public:
  /// `base` (optional) gives the undeformed height; otherwise params.grid.base_height_m.
  /// Throws ConfigError on invalid parameters.
  explicit ScmTerrain(const ScmParams& params,
                      std::shared_ptr<const terrain::TerrainSurface> base = nullptr);
  ~ScmTerrain() override;
  ScmTerrain(const ScmTerrain&) = delete;
  ScmTerrain& operator=(const ScmTerrain&) = delete;

  // ---- TerrainSurface: the current deformed surface (bilinear between vertices) ----
  double height(double x, double y) const override;
  Vec3 normal(double x, double y) const override;
  /// tan(friction angle) of the soil (for code that needs a Coulomb coefficient).
  double friction(double x, double y) const override;

  // ---- WheelTerrainContact ----
  /// Wheels are solid cylinders (radius, width, axis = wheel local y). One call = one step of
  /// length dt: the soil deforms and loads[k] receives the force/torque on wheel k.
  void compute_wheel_loads(std::span<const terrain::WheelBodyState> wheels, double dt,
                           std::span<terrain::WheelLoad> loads) override;
  /// The same for bodies of any supported shape.
  void compute_body_loads(std::span<const ContactBody> bodies, double dt,
                          std::span<terrain::WheelLoad> loads);

  // ---- Deformation sync (see docs/scm.md, "Sync rule") ----
  /// Id of this process's changes in conflicts (tie-break only). Default 0.
  void set_source_id(std::uint32_t id) { replication_.set_source_id(id); }
  std::uint32_t source_id() const { return replication_.source_id(); }
  /// Ends the local part of a frame: returns every vertex whose shared state this process
  /// changed since the last call (sorted by (i, j)) and opens the frame's merge window.
  /// Call exactly once per frame, also when no local body exists, before applying remote lists.
  std::vector<VertexChange> take_local_changes();
  /// Merges another process's list for the same frame. Per vertex, among all records of the
  /// frame (own and remote) the lowest level wins (ties: larger plastic sinkage, larger yield,
  /// lower level_initial, then lower source id), so the result does not depend on arrival order.
  void apply_remote_changes(std::uint32_t source_id, std::span<const VertexChange> changes);
  /// Interest management (docs/scm.md): from now on remote records farther than `radius_m`
  /// (in x or y) from (x, y) wait aside and the deferred ones within it are merged. Call at the
  /// start of a frame, before apply_remote_changes; this process's bodies must stay within the
  /// box until the next call.
  void set_interest_region(double x_m, double y_m, double radius_m);
  /// The vertex box set_interest_region uses for a square of half-side radius_m around (x, y).
  Replication::IndexBox interest_box(double x_m, double y_m, double radius_m) const;
  /// Soil routing (docs/scm.md, "Routing"; tile boxes, see Replication). The keeper's state of
  /// the tiles of `now` not in `before` (throws std::logic_error while records are deferred).
  std::vector<VertexChange> added_tiles_state(const Replication::IndexBox& now,
                                              const Replication::IndexBox& before) const;
  /// A routed vehicle loads that state (Replication::load_added_tiles).
  void load_added_tiles(const Replication::IndexBox& now, const Replication::IndexBox& before,
                        std::span<const VertexChange> state) {
    replication_.load_added_tiles(grid_, now, before, state);
  }
  void drop_tiles_outside(const Replication::IndexBox& keep) {
    replication_.drop_tiles_outside(keep);
  }
  /// Merges everything deferred (the grid then equals a full merge everywhere).
  void flush_deferred() { replication_.flush_deferred(grid_); }
  std::size_t deferred_vertices() const { return replication_.deferred_vertices(); }
  /// Whole-grid state (throws std::logic_error while records are deferred: flush first).
  ScmSnapshot snapshot() const;
  /// Replaces the whole grid (throws std::invalid_argument on a spacing mismatch).
  void load_snapshot(const ScmSnapshot& snapshot);
  /// FNV-1a over the shared state of all stored vertices in (i, j) order (throws
  /// std::logic_error while records are deferred: flush first).
  std::uint64_t grid_hash() const;

  // ---- Queries ----
  const ScmParams& params() const { return params_; }
  double spacing() const { return grid_.spacing(); }
  /// True if vertex (i, j) is inside the deformable area.
  bool in_area(std::int32_t i, std::int32_t j) const { return grid_.in_area(i, j); }
  std::int32_t i_min() const { return grid_.i_min(); }
  std::int32_t i_max() const { return grid_.i_max(); }
  std::int32_t j_min() const { return grid_.j_min(); }
  std::int32_t j_max() const { return grid_.j_max(); }
  /// Undeformed height of vertex (i, j) (base surface or flat base height).
  double base_height(std::int32_t i, std::int32_t j) const { return grid_.base_height(i, j); }
  /// Current height of vertex (i, j).
  double vertex_height(std::int32_t i, std::int32_t j) const { return grid_.level_of(i, j); }
  /// Stored shared state of vertex (i, j), if it ever deformed.
  std::optional<VertexChange> vertex(std::int32_t i, std::int32_t j) const;
  std::size_t stored_vertices() const { return grid_.size(); }
  /// No stored level or unloaded surface is above this (bodies above it touch no soil).
  double level_bound() const { return grid_.level_bound(); }
  /// Normal stress at vertex (i, j) in the last step (0 if not in contact then).
  double vertex_pressure(std::int32_t i, std::int32_t j) const;
  /// Sum over stored vertices of (level_initial - sinkage_plastic - base) * cell area (m^3):
  /// zero while bulldozing with flow_factor 1 conserves the soil (see docs/scm.md).
  double plastic_volume_change_m3() const;
  const ScmStepStats& last_step_stats() const { return stats_; }

  // ---- Checkpoints (docs/scm.md, "Checkpoint state") ----
  /// Writes everything that decides later steps, merges, hashes and stats, between frames:
  /// the stored vertices sparsely (sorted by (i, j)), the pending outgoing changes, the open
  /// merge window, the interest box and the deferred records, the step counter and the last
  /// step's stats, after a fingerprint of the grid geometry and soil parameters. Equal states
  /// write equal bytes (no hash-map or insertion order leaks in).
  void save_state(core::StateWriter& w) const;
  /// Restores a state written by save_state into a terrain built from the same parameters
  /// (and base surface). Throws core::StateError naming the parameter when the state is of
  /// another grid or soil, or when the bytes are damaged; the terrain is then unusable (build
  /// a new one).
  void load_state(core::StateReader& r);

 private:
  struct StepData;  // per-step work arrays and the bulldozer (scm_terrain.cpp)

  /// The cell under (x, y): corner levels and fractions; nullopt far outside any grid.
  struct Cell {
    double tu, tv, h00, h10, h01, h11;
  };
  std::optional<Cell> cell_at(double x, double y) const;
  // The steps of compute_body_loads, in order.
  std::size_t place_bodies(std::span<const ContactBody> bodies);
  void cast_rays(std::size_t total);
  void collect_contacts(std::size_t total);
  void apply_soil_law(double dt);
  void integrate_loads(std::span<terrain::WheelLoad> loads);

  ScmParams params_;
  VertexGrid grid_;
  SoilLaw law_;
  Replication replication_;
  std::int64_t step_ = 0;
  ScmStepStats stats_;
  std::unique_ptr<StepData> step_data_;
  std::unique_ptr<ThreadPool> pool_;
};

}  // namespace syndds::scm
