#pragma once
// Storage of the SCM grid: the deformable area, the undeformed (base) height and the sparse set
// of vertices that ever deformed, each a VertexRecord found through the (i, j) hash index of
// vertex_map.hpp. It also keeps the two pieces of bookkeeping every writer must update: the
// dirty list (vertices whose shared state changed since replication last took them) and the
// level bound (no stored level or unloaded surface is above it, so a body above it touches
// nothing). The contact law, bulldozing and replication all read and write through this class.
#include <cstdint>
#include <memory>
#include <vector>

#include "scm/scm_params.hpp"
#include "scm/vertex_map.hpp"
#include "terrain/terrain.hpp"

namespace syndds::core {
class StateWriter;
class StateReader;
}  // namespace syndds::core

namespace syndds::scm {

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

/// A stored vertex: the shared state of VertexChange plus this process's contact state.
struct VertexRecord {
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
  bool dirty = false;  // in the dirty list (changed since take_dirty)
};

VertexChange to_change(const VertexRecord& r);

class VertexGrid {
 public:
  /// `base` (optional) gives the undeformed height; otherwise grid.base_height_m.
  VertexGrid(const GridParams& grid, std::shared_ptr<const terrain::TerrainSurface> base);

  double spacing() const { return delta_; }
  double cell_area() const { return cell_area_; }
  bool in_area(std::int32_t i, std::int32_t j) const {
    return i >= i_min_ && i <= i_max_ && j >= j_min_ && j <= j_max_;
  }
  std::int32_t i_min() const { return i_min_; }
  std::int32_t i_max() const { return i_max_; }
  std::int32_t j_min() const { return j_min_; }
  std::int32_t j_max() const { return j_max_; }
  const terrain::TerrainSurface* base() const { return base_.get(); }
  double base_height_m() const { return base_height_m_; }

  /// Undeformed height of vertex (i, j) (base surface or flat base height).
  double base_height(std::int32_t i, std::int32_t j) const {
    if (base_) return base_->height(i * delta_, j * delta_);
    return base_height_m_;
  }
  /// Current height of vertex (i, j).
  double level_of(std::int32_t i, std::int32_t j) const {
    const std::int32_t r = find(i, j);
    return r >= 0 ? records_[static_cast<std::size_t>(r)].level : base_height(i, j);
  }
  /// Height of the unloaded soil, level_initial - sinkage_plastic: a body below it is in contact.
  double surface_of(std::int32_t i, std::int32_t j) const {
    const std::int32_t r = find(i, j);
    if (r < 0) return base_height(i, j);
    const VertexRecord& rec = records_[static_cast<std::size_t>(r)];
    return rec.level_initial - rec.sinkage_plastic;
  }
  /// No stored level or unloaded surface is above this (infinite over a base surface).
  double level_bound() const { return level_bound_; }
  void note_level(double level) {
    if (level > level_bound_) level_bound_ = level;
  }

  /// Index of the record of (i, j), or -1.
  std::int32_t find(std::int32_t i, std::int32_t j) const { return index_.find(vertex_key(i, j)); }
  /// Index of the record of (i, j); a new record starts undeformed and is marked dirty.
  std::int32_t get_or_insert(std::int32_t i, std::int32_t j);
  /// Index of the record of (i, j); a new record is blank (shared state zero, not dirty), for a
  /// caller that assigns the shared state next.
  std::int32_t get_or_insert_blank(std::int32_t i, std::int32_t j);
  VertexRecord& record(std::int32_t index) { return records_[static_cast<std::size_t>(index)]; }
  const VertexRecord& record(std::int32_t index) const {
    return records_[static_cast<std::size_t>(index)];
  }
  const std::vector<VertexRecord>& records() const { return records_; }
  std::size_t size() const { return records_.size(); }

  /// Sets the shared state of a record from a change (and raises the level bound).
  void assign(VertexRecord& r, const VertexChange& c);
  void mark_dirty(std::int32_t index) {
    VertexRecord& r = records_[static_cast<std::size_t>(index)];
    if (!r.dirty) {
      r.dirty = true;
      dirty_.push_back(index);
    }
  }
  /// Calls fn(record) for each record marked dirty, in marking order, and clears the marks.
  template <class Fn>
  void take_dirty(Fn&& fn) {
    for (const std::int32_t idx : dirty_) {
      VertexRecord& r = records_[static_cast<std::size_t>(idx)];
      r.dirty = false;
      fn(static_cast<const VertexRecord&>(r));
    }
    dirty_.clear();
  }
  std::size_t dirty_count() const { return dirty_.size(); }
  /// Forgets every stored vertex (the grid is undeformed again).
  void clear();

  /// Checkpoint state (docs/scm.md, "Checkpoint state"): the stored vertices sparsely, sorted
  /// by (i, j), with their dirty marks, and the level bound. `last_step` is the index of the
  /// last step taken (the soil law's contact state is relative to it).
  void save_state(core::StateWriter& w, std::int64_t last_step) const;
  /// Replaces every stored vertex by those of the state; throws core::StateError on a vertex
  /// outside the area, out of order or with unknown flags.
  void load_state(core::StateReader& r, std::int64_t last_step);
  /// Largest size of one vertex in save_state (bytes): the bound on a checkpoint's growth.
  static constexpr std::size_t kMaxStateRecordBytes = 2 * 4 + 1 + 7 * 8;

 private:
  std::shared_ptr<const terrain::TerrainSurface> base_;
  double base_height_m_ = 0.0;
  double delta_ = 0.05;
  double cell_area_ = 0.0025;
  std::int32_t i_min_ = 0, i_max_ = 0, j_min_ = 0, j_max_ = 0;
  KeyIndexMap index_;                  // vertex key -> records_ index
  std::vector<VertexRecord> records_;  // stored vertices (insertion order)
  std::vector<std::int32_t> dirty_;
  double level_bound_ = 0.0;
};

}  // namespace syndds::scm
