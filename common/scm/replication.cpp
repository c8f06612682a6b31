#include "scm/replication.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/error.hpp"
#include "core/hash.hpp"

namespace syndds::scm {
namespace {

bool ij_less(const VertexChange& a, const VertexChange& b) {
  return a.i != b.i ? a.i < b.i : a.j < b.j;
}

}  // namespace

bool beats(const VertexChange& a, std::uint32_t sa, const VertexChange& b, std::uint32_t sb) {
  if (a.level_m != b.level_m) return a.level_m < b.level_m;
  if (a.sinkage_plastic_m != b.sinkage_plastic_m) return a.sinkage_plastic_m > b.sinkage_plastic_m;
  if (a.sigma_yield_pa != b.sigma_yield_pa) return a.sigma_yield_pa > b.sigma_yield_pa;
  if (a.level_initial_m != b.level_initial_m) return a.level_initial_m < b.level_initial_m;
  return sa < sb;
}

std::vector<VertexChange> Replication::take_local_changes(VertexGrid& grid) {
  claims_.clear();
  claim_source_.clear();
  std::vector<VertexChange> out;
  out.reserve(grid.dirty_count());
  grid.take_dirty([&](const VertexRecord& r) {
    out.push_back(to_change(r));
    claims_.insert(vertex_key(r.i, r.j), static_cast<std::int32_t>(claim_source_.size()));
    claim_source_.push_back(source_id_);
  });
  std::sort(out.begin(), out.end(), ij_less);
  return out;
}

void Replication::apply_remote_changes(VertexGrid& grid, std::uint32_t source_id,
                                       std::span<const VertexChange> changes) {
  for (const VertexChange& c : changes) {
    if (!grid.in_area(c.i, c.j) || !std::isfinite(c.level_m) || !std::isfinite(c.level_initial_m) ||
        !std::isfinite(c.sinkage_plastic_m) || !std::isfinite(c.sigma_yield_pa)) {
      throw ProtocolError("SCM change from source " + std::to_string(source_id) + " at (" +
                          std::to_string(c.i) + ", " + std::to_string(c.j) +
                          ") is outside the area or not finite (terrain configs differ?)");
    }
  }
  for (const VertexChange& c : changes) {
    const std::uint64_t key = vertex_key(c.i, c.j);
    const auto next = static_cast<std::int32_t>(claim_source_.size());
    const std::int32_t claim = claims_.insert(key, next);
    VertexRecord& rec = grid.record(grid.get_or_insert_blank(c.i, c.j));
    if (claim == next) {  // first record of this frame for the vertex
      claim_source_.push_back(source_id);
      grid.assign(rec, c);
      continue;
    }
    auto& holder = claim_source_[static_cast<std::size_t>(claim)];
    if (beats(c, source_id, to_change(rec), holder)) {
      grid.assign(rec, c);
      holder = source_id;
    }
  }
}

ScmSnapshot Replication::snapshot(const VertexGrid& grid) {
  ScmSnapshot snap;
  snap.spacing_m = grid.spacing();
  snap.vertices.reserve(grid.size());
  for (const VertexRecord& r : grid.records()) snap.vertices.push_back(to_change(r));
  std::sort(snap.vertices.begin(), snap.vertices.end(), ij_less);
  return snap;
}

void Replication::load_snapshot(VertexGrid& grid, const ScmSnapshot& snap) {
  if (snap.spacing_m != grid.spacing()) {
    throw std::invalid_argument("ScmTerrain::load_snapshot: spacing " +
                                std::to_string(snap.spacing_m) + " differs from " +
                                std::to_string(grid.spacing()));
  }
  for (const VertexChange& c : snap.vertices) {
    if (!grid.in_area(c.i, c.j)) {
      throw std::invalid_argument("ScmTerrain::load_snapshot: vertex outside the area");
    }
  }
  grid.clear();
  claims_.clear();
  claim_source_.clear();
  for (const VertexChange& c : snap.vertices) {
    grid.assign(grid.record(grid.get_or_insert_blank(c.i, c.j)), c);
  }
}

std::uint64_t Replication::grid_hash(const VertexGrid& grid) {
  const std::vector<VertexChange> all = snapshot(grid).vertices;
  Fnv1a64 h;
  for (const VertexChange& c : all) {
    h.add_bytes(&c.i, sizeof c.i);
    h.add_bytes(&c.j, sizeof c.j);
    h.add(c.level_m);
    h.add(c.level_initial_m);
    h.add(c.sinkage_plastic_m);
    h.add(c.sigma_yield_pa);
  }
  return h.value();
}

}  // namespace syndds::scm
