#pragma once
// Replication of the SCM grid between processes (docs/scm.md, "Sync rule"): each process
// computes only its own bodies, publishes the vertices whose shared state it changed in a frame
// and merges the other processes' lists for the same frame; a late joiner loads a snapshot.
// Owns only the per-frame merge state (which record of the frame holds each vertex); the
// vertices themselves are in the VertexGrid.
#include <cstdint>
#include <span>
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
  /// outside the area or a value that is not finite).
  void apply_remote_changes(VertexGrid& grid, std::uint32_t source_id,
                            std::span<const VertexChange> changes);
  static ScmSnapshot snapshot(const VertexGrid& grid);
  /// Replaces the whole grid (throws std::invalid_argument on a spacing mismatch or a vertex
  /// outside the area) and closes the merge window.
  void load_snapshot(VertexGrid& grid, const ScmSnapshot& snapshot);
  /// FNV-1a over the shared state of all stored vertices in (i, j) order.
  static std::uint64_t grid_hash(const VertexGrid& grid);

 private:
  std::uint32_t source_id_ = 0;
  KeyIndexMap claims_;                       // vertex key -> claim_source_ index (frame winners)
  std::vector<std::uint32_t> claim_source_;  // indexed by claims_ values
};

}  // namespace syndds::scm
