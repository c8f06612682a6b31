#pragma once
// Replication of the SCM grid between processes (docs/scm.md, "Sync rule"): each process
// computes only its own bodies, publishes the vertices whose shared state it changed in a frame
// and merges the other processes' lists for the same frame; a late joiner loads a snapshot.
// Owns only the per-frame merge state (which record of the frame holds each vertex); the
// vertices themselves are in the VertexGrid.
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "scm/vertex_grid.hpp"
#include "scm/vertex_map.hpp"

namespace syndds::scm {

/// Whole-grid state for a late joiner: every stored vertex, sorted by (i, j).
struct ScmSnapshot {
  double spacing_m = 0.0;
  std::vector<VertexChange> vertices;
};

/// Total order over records of one vertex: true if (a, sa) beats (b, sb): the lowest level wins
/// (ties: larger plastic sinkage, larger yield, lower level_initial, then lower source id).
bool beats(const VertexChange& a, std::uint32_t sa, const VertexChange& b, std::uint32_t sb);

class Replication {
 public:
  /// Id of this process's changes in conflicts (tie-break only). Default 0.
  void set_source_id(std::uint32_t id) { source_id_ = id; }
  std::uint32_t source_id() const { return source_id_; }

  /// The grid's dirty vertices as changes sorted by (i, j); opens the frame's merge window
  /// with them as this process's claims.
  std::vector<VertexChange> take_local_changes(VertexGrid& grid);
  /// Merges another process's list for the same frame (throws ProtocolError on a vertex
  /// outside the area or a value that is not finite). Records outside the interest box (when
  /// one is set) are deferred instead: see set_interest.
  void apply_remote_changes(VertexGrid& grid, std::uint32_t source_id,
                            std::span<const VertexChange> changes);

  /// Interest management. Vertex index box [i_lo, i_hi] x [j_lo, j_hi]: remote records outside
  /// it are kept aside per tile of kTileSize x kTileSize vertices, one slot per vertex holding
  /// what the merge would have left there (a newer frame's first record replaces it, a record
  /// of the same frame replaces it if it beats it); the grid's level bound takes them in when
  /// they are merged. Tiles that meet the box are merged into the grid now, before this
  /// frame's lists. The caller guarantees that this process changes no vertex outside the box
  /// until the next call; then the grid inside the box equals the grid of a full merge.
  struct IndexBox {
    std::int32_t i_lo = 0, i_hi = -1, j_lo = 0, j_hi = -1;
  };
  void set_interest(VertexGrid& grid, const IndexBox& box);
  /// No box any more: every deferred tile is merged now and nothing is deferred from now on.
  void clear_interest(VertexGrid& grid);
  /// Merges every deferred tile (the grid then equals a full merge everywhere).
  void flush_deferred(VertexGrid& grid);
  /// Soil routing (docs/scm.md, "Routing"). Tile boxes are IndexBoxes in tile indices (vertex
  /// index >> kTileShift, inclusive). `tiles_of` is the box of the tiles a vertex box meets;
  /// `added_tiles(now, before, fn)` calls fn(ti, tj) for the tiles of `now` not in `before`, in
  /// key order.
  static IndexBox tiles_of(const IndexBox& vertices);
  static bool contains(const IndexBox& box, std::int32_t i, std::int32_t j) {
    return i >= box.i_lo && i <= box.i_hi && j >= box.j_lo && j <= box.j_hi;
  }
  template <class Fn>
  static void added_tiles(const IndexBox& now, const IndexBox& before, Fn&& fn) {
    for (std::int32_t ti = now.i_lo; ti <= now.i_hi; ++ti) {
      for (std::int32_t tj = now.j_lo; tj <= now.j_hi; ++tj) {
        if (!contains(before, ti, tj)) fn(ti, tj);
      }
    }
  }
  /// Every stored vertex of `grid` in the tiles of `now` not in `before`, sorted by (i, j):
  /// what the soil keeper sends a vehicle whose box grew from `before` to `now`.
  static std::vector<VertexChange> added_tiles_state(const VertexGrid& grid, const IndexBox& now,
                                                     const IndexBox& before);
  /// A vehicle's side of it: what it held aside for the tiles of `now` not in `before` is
  /// replaced by `state` (the keeper's, from added_tiles_state), older than this frame's merge
  /// window, and merged into the grid when a tile meets the interest box; nothing of those
  /// tiles may be inside the current box. Throws ProtocolError on a record outside those tiles
  /// or the area, or not finite.
  void load_added_tiles(const VertexGrid& grid, const IndexBox& now, const IndexBox& before,
                        std::span<const VertexChange> state);
  /// Forgets what is held aside for tiles outside `keep` (a tile box): they are no longer
  /// received, and load_added_tiles replaces them if they come back.
  void drop_tiles_outside(const IndexBox& keep);
  std::size_t deferred_tiles() const { return deferred_.size(); }
  std::size_t deferred_vertices() const { return deferred_vertices_; }
  static constexpr std::int32_t kTileShift = 5;  // tiles of 32 x 32 vertices
  static constexpr std::int32_t kTileSize = 1 << kTileShift;
  static ScmSnapshot snapshot(const VertexGrid& grid);
  /// Replaces the whole grid (throws std::invalid_argument on a spacing mismatch or a vertex
  /// outside the area) and closes the merge window.
  void load_snapshot(VertexGrid& grid, const ScmSnapshot& snapshot);
  /// FNV-1a over the shared state of all stored vertices in (i, j) order.
  static std::uint64_t grid_hash(const VertexGrid& grid);

  /// Checkpoint state: source id, merge window and its claims, interest box, deferred records
  /// (in key order). The vertices themselves are the grid's (VertexGrid::save_state).
  void save_state(core::StateWriter& w) const;
  /// Throws core::StateError on records outside `grid`'s area or damaged bookkeeping.
  void load_state(core::StateReader& r, const VertexGrid& grid);

 private:
  struct DeferredSlot {
    VertexChange change;
    std::uint32_t source = 0;
    std::uint64_t window = 0;  // merge window (frame) of the record; 0: empty slot
  };
  // Sparse: a rut crosses a tile on a few hundred of its 1024 vertices, and a process defers
  // every far-away rut of the run: a dense tile (57 kB, zeroed when made) made the deferred
  // storage the largest source of fresh pages (page faults) of a soft-soil vehicle.
  struct DeferredTile {
    std::vector<std::uint16_t> where;  // kTileSize^2, row i-major: 1 + index in `slots`, 0: none
    std::vector<DeferredSlot> slots;   // the used slots, in the order they were first deferred
    std::size_t used() const { return slots.size(); }
    // The used slots in slot order: fn(slot index, slot).
    template <class Fn>
    void for_each_used(Fn&& fn) const {
      for (std::size_t s = 0; s < where.size(); ++s) {
        if (where[s] != 0) fn(s, slots[where[s] - 1u]);
      }
    }
  };
  bool outside_interest(std::int32_t i, std::int32_t j) const {
    return has_interest_ && (i < interest_.i_lo || i > interest_.i_hi || j < interest_.j_lo ||
                             j > interest_.j_hi);
  }
  void defer(std::uint32_t source_id, const VertexChange& c);
  void merge_tile(VertexGrid& grid, DeferredTile& tile);

  std::uint32_t source_id_ = 0;
  KeyIndexMap claims_;                       // vertex key -> claim_source_ index (frame winners)
  std::vector<std::uint32_t> claim_source_;  // indexed by claims_ values
  std::uint64_t window_ = 1;                 // merge windows opened so far (+1)
  bool has_interest_ = false;
  IndexBox interest_;
  void erase_tile(std::uint64_t key);
  void forget_deferred();

  std::unordered_map<std::uint64_t, DeferredTile> deferred_;  // by tile key
  std::size_t deferred_vertices_ = 0;                          // slots used in all tiles
  // The tile the last deferred record went to (records come sorted by (i, j), so runs of
  // them fall into one tile); map nodes stay put until erased.
  std::uint64_t last_tile_key_ = 0;
  DeferredTile* last_tile_ = nullptr;
};

}  // namespace syndds::scm
