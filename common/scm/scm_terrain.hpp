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
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <variant>
#include <vector>

#include "core/math.hpp"
#include "scm/scm_params.hpp"
#include "scm/vertex_map.hpp"
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

/// One vertex's shared (synchronised) state: everything a receiver needs for a faithful copy.
/// 40 bytes on the wire: two 32-bit indices and four doubles.
struct VertexChange {
  std::int32_t i = 0;
  std::int32_t j = 0;
  double level_m = 0.0;            // current surface height (m)
  double level_initial_m = 0.0;    // undeformed height incl. bulldozed material (m)
  double sinkage_plastic_m = 0.0;  // plastic (permanent) sinkage below level_initial (m)
  double sigma_yield_pa = 0.0;     // highest Bekker stress reached, the reloading limit (Pa)

  friend bool operator==(const VertexChange&, const VertexChange&) = default;
};

/// Whole-grid state for a late joiner: every stored vertex, sorted by (i, j).
struct ScmSnapshot {
  double spacing_m = 0.0;
  std::vector<VertexChange> vertices;
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
  void set_source_id(std::uint32_t id) { source_id_ = id; }
  std::uint32_t source_id() const { return source_id_; }
  /// Ends the local part of a frame: returns every vertex whose shared state this process
  /// changed since the last call (sorted by (i, j)) and opens the frame's merge window.
  /// Call exactly once per frame, also when no local body exists, before applying remote lists.
  std::vector<VertexChange> take_local_changes();
  /// Merges another process's list for the same frame. Per vertex, among all records of the
  /// frame (own and remote) the lowest level wins (ties: larger plastic sinkage, larger yield,
  /// lower level_initial, then lower source id), so the result does not depend on arrival order.
  void apply_remote_changes(std::uint32_t source_id, std::span<const VertexChange> changes);
  ScmSnapshot snapshot() const;
  /// Replaces the whole grid (throws std::invalid_argument on a spacing mismatch).
  void load_snapshot(const ScmSnapshot& snapshot);
  /// FNV-1a over the shared state of all stored vertices in (i, j) order.
  std::uint64_t grid_hash() const;

  // ---- Queries ----
  const ScmParams& params() const { return params_; }
  double spacing() const { return delta_; }
  /// True if vertex (i, j) is inside the deformable area.
  bool in_area(std::int32_t i, std::int32_t j) const {
    return i >= i_min_ && i <= i_max_ && j >= j_min_ && j <= j_max_;
  }
  std::int32_t i_min() const { return i_min_; }
  std::int32_t i_max() const { return i_max_; }
  std::int32_t j_min() const { return j_min_; }
  std::int32_t j_max() const { return j_max_; }
  /// Undeformed height of vertex (i, j) (base surface or flat base height).
  double base_height(std::int32_t i, std::int32_t j) const;
  /// Current height of vertex (i, j).
  double vertex_height(std::int32_t i, std::int32_t j) const;
  /// Stored shared state of vertex (i, j), if it ever deformed.
  std::optional<VertexChange> vertex(std::int32_t i, std::int32_t j) const;
  std::size_t stored_vertices() const { return records_.size(); }
  /// Normal stress at vertex (i, j) in the last step (0 if not in contact then).
  double vertex_pressure(std::int32_t i, std::int32_t j) const;
  /// Sum over stored vertices of (level_initial - sinkage_plastic - base) * cell area (m^3):
  /// zero while bulldozing with flow_factor 1 conserves the soil (see docs/scm.md).
  double plastic_volume_change_m3() const;
  const ScmStepStats& last_step_stats() const { return stats_; }

 private:
  struct Record {
    // Shared state (synchronised, hashed).
    double level = 0.0;
    double level_initial = 0.0;
    double sinkage_plastic = 0.0;
    double sigma_yield = 0.0;
    // Local contact state (never synchronised): belongs to this process's own bodies.
    double shear_x = 0.0;            // shear mobilisation m = tau / tau_max (vector, |m| <= 1)
    double shear_y = 0.0;            //   along the body's slip over this vertex (see the law)
    double sigma = 0.0;              // normal stress of the last step in contact (Pa)
    double step_plastic_flow = 0.0;  // plastic sinkage added in the last step (m)
    std::int64_t contact_step = -2;  // index of the last step in contact
    std::int32_t i = 0;
    std::int32_t j = 0;
    bool dirty = false;  // in dirty_ (changed since take_local_changes)
  };

  struct Scratch;  // per-step work arrays, kept between calls to avoid allocations

  std::int32_t find_record(std::int32_t i, std::int32_t j) const {
    return index_.find(vertex_key(i, j));
  }
  std::int32_t get_or_insert_record(std::int32_t i, std::int32_t j);
  void mark_dirty(std::int32_t index);
  double level_of(std::int32_t i, std::int32_t j) const;
  /// The grid cell under (x, y): corner levels and fractions; nullopt far outside any grid.
  struct Cell {
    double tu, tv, h00, h10, h01, h11;
  };
  std::optional<Cell> cell_at(double x, double y) const;
  /// Height of the unloaded soil, level_initial - sinkage_plastic: a body below it is in contact.
  double surface_of(std::int32_t i, std::int32_t j) const;
  void note_level(double level);
  /// Footprint entry of vertex (i, j) in this step (the first body box holding it), or -1.
  std::int32_t find_step_vertex(std::int32_t i, std::int32_t j) const;
  void bulldoze();
  void bulldoze_window(std::size_t p_begin, std::size_t p_end,
                       const std::array<std::int64_t, 4>& window);
  static VertexChange to_change(const Record& r);
  void assign(Record& r, const VertexChange& c);

  ScmParams params_;
  std::shared_ptr<const terrain::TerrainSurface> base_;
  double delta_ = 0.05;
  double cell_area_ = 0.0025;
  double tan_phi_ = 0.0;
  std::int32_t i_min_ = 0, i_max_ = 0, j_min_ = 0, j_max_ = 0;
  std::uint32_t source_id_ = 0;

  KeyIndexMap index_;            // vertex key -> records_ index
  std::vector<Record> records_;  // stored vertices (insertion order)
  std::vector<std::int32_t> dirty_;
  KeyIndexMap claims_;        // vertex key -> claim_source_ index (this frame's winners)
  double level_bound_ = 0.0;  // no level or unloaded surface is above this (flat base only)
  std::int64_t step_ = 0;
  ScmStepStats stats_;

  std::vector<std::uint32_t> claim_source_;  // indexed by claims_ values
  std::unique_ptr<Scratch> scratch_;
  std::unique_ptr<ThreadPool> pool_;
};

}  // namespace syndds::scm
