#include "scm/replication.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/state_io.hpp"

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
  ++window_;
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
    if (outside_interest(c.i, c.j)) {
      defer(source_id, c);
      continue;
    }
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

// The same decisions as the merge above makes for a vertex, on the vertex's slot instead of
// its grid record: the first record of a window replaces what an older window left, a later
// record of the same window replaces it if it beats it. The level bound is not raised: it is
// raised when the tile is merged, and until then it only has to cover the soil under this
// process's bodies, which is inside the box (ScmTerrain::place_bodies).
void Replication::defer(std::uint32_t source_id, const VertexChange& c) {
  const std::uint64_t tile_key = vertex_key(c.i >> kTileShift, c.j >> kTileShift);
  if (!last_tile_ || last_tile_key_ != tile_key) {
    last_tile_ = &deferred_[tile_key];
    last_tile_key_ = tile_key;
  }
  DeferredTile& tile = *last_tile_;
  if (tile.where.empty()) tile.where.assign(static_cast<std::size_t>(kTileSize * kTileSize), 0);
  std::uint16_t& where = tile.where[static_cast<std::size_t>(((c.i & (kTileSize - 1)) << kTileShift) |
                                                            (c.j & (kTileSize - 1)))];
  if (where == 0) {
    tile.slots.emplace_back();
    where = static_cast<std::uint16_t>(tile.slots.size());
    ++deferred_vertices_;
  }
  DeferredSlot& slot = tile.slots[where - 1u];
  if (slot.window != window_ || beats(c, source_id, slot.change, slot.source)) {
    slot.change = c;
    slot.source = source_id;
    slot.window = window_;
  }
}

Replication::IndexBox Replication::tiles_of(const IndexBox& v) {
  return {v.i_lo >> kTileShift, v.i_hi >> kTileShift, v.j_lo >> kTileShift, v.j_hi >> kTileShift};
}

std::vector<VertexChange> Replication::added_tiles_state(const VertexGrid& grid,
                                                         const IndexBox& now,
                                                         const IndexBox& before) {
  std::vector<VertexChange> out;
  added_tiles(now, before, [&](std::int32_t ti, std::int32_t tj) {
    const std::int32_t i0 = std::max(ti * kTileSize, grid.i_min());
    const std::int32_t i1 = std::min(ti * kTileSize + kTileSize - 1, grid.i_max());
    const std::int32_t j0 = std::max(tj * kTileSize, grid.j_min());
    const std::int32_t j1 = std::min(tj * kTileSize + kTileSize - 1, grid.j_max());
    for (std::int32_t i = i0; i <= i1; ++i) {
      for (std::int32_t j = j0; j <= j1; ++j) {
        const std::int32_t r = grid.find(i, j);
        if (r >= 0) out.push_back(to_change(grid.records()[static_cast<std::size_t>(r)]));
      }
    }
  });
  std::sort(out.begin(), out.end(), ij_less);
  return out;
}

void Replication::load_added_tiles(const VertexGrid& grid, const IndexBox& now,
                                   const IndexBox& before, std::span<const VertexChange> state) {
  if (window_ < 2) throw std::logic_error("Replication::load_added_tiles before the first frame");
  for (const VertexChange& c : state) {
    const std::int32_t ti = c.i >> kTileShift, tj = c.j >> kTileShift;
    if (!contains(now, ti, tj) || contains(before, ti, tj) || !grid.in_area(c.i, c.j) ||
        !std::isfinite(c.level_m) || !std::isfinite(c.level_initial_m) ||
        !std::isfinite(c.sinkage_plastic_m) || !std::isfinite(c.sigma_yield_pa)) {
      throw ProtocolError("SCM tile state at (" + std::to_string(c.i) + ", " +
                          std::to_string(c.j) +
                          ") is outside the tiles added to the box, outside the area or not "
                          "finite");
    }
  }
  const IndexBox interest_tiles = tiles_of(interest_);
  added_tiles(now, before, [&](std::int32_t ti, std::int32_t tj) {
    if (has_interest_ && contains(interest_tiles, ti, tj)) {
      throw std::logic_error("Replication::load_added_tiles: tile (" + std::to_string(ti) + ", " +
                             std::to_string(tj) + ") is in the interest box already");
    }
    if (deferred_.count(vertex_key(ti, tj)) > 0) erase_tile(vertex_key(ti, tj));
  });
  // The records of the previous window (what the keeper merged) are each vertex's state: this
  // window's records replace them whatever they are.
  const std::uint64_t window = window_;
  window_ = window - 1;
  for (const VertexChange& c : state) defer(0, c);
  window_ = window;
}

void Replication::drop_tiles_outside(const IndexBox& keep) {
  std::vector<std::uint64_t> gone;
  for (const auto& [key, tile] : deferred_) {
    if (!contains(keep, key_i(key), key_j(key))) gone.push_back(key);
  }
  for (const std::uint64_t key : gone) erase_tile(key);
}

void Replication::merge_tile(VertexGrid& grid, DeferredTile& tile) {
  tile.for_each_used([&](std::size_t, const DeferredSlot& slot) {
    grid.assign(grid.record(grid.get_or_insert_blank(slot.change.i, slot.change.j)), slot.change);
  });
}

void Replication::set_interest(VertexGrid& grid, const IndexBox& box) {
  has_interest_ = true;
  interest_ = box;
  if (deferred_.empty() || box.i_hi < box.i_lo || box.j_hi < box.j_lo) return;
  // Tiles meeting the box, in key order so the grid's insertion order does not depend on the
  // hash map's. The box spans few tiles and the map may hold thousands (every rut far away):
  // look the box's tiles up rather than walk the map, whichever is fewer.
  const std::int32_t ti_lo = box.i_lo >> kTileShift, ti_hi = box.i_hi >> kTileShift;
  const std::int32_t tj_lo = box.j_lo >> kTileShift, tj_hi = box.j_hi >> kTileShift;
  const auto box_tiles = static_cast<std::size_t>(ti_hi - ti_lo + 1) *
                         static_cast<std::size_t>(tj_hi - tj_lo + 1);
  std::vector<std::uint64_t> due;
  if (box_tiles < deferred_.size()) {
    for (std::int32_t ti = ti_lo; ti <= ti_hi; ++ti) {
      for (std::int32_t tj = tj_lo; tj <= tj_hi; ++tj) {
        const std::uint64_t key = vertex_key(ti, tj);
        if (deferred_.count(key) > 0) due.push_back(key);
      }
    }
  } else {
    for (const auto& [key, tile] : deferred_) {
      const std::int32_t ti = key_i(key);
      const std::int32_t tj = key_j(key);
      if (ti >= ti_lo && ti <= ti_hi && tj >= tj_lo && tj <= tj_hi) due.push_back(key);
    }
  }
  std::sort(due.begin(), due.end());
  for (const std::uint64_t key : due) {
    merge_tile(grid, deferred_.at(key));
    erase_tile(key);
  }
}

void Replication::erase_tile(std::uint64_t key) {
  auto it = deferred_.find(key);
  deferred_vertices_ -= it->second.used();
  if (last_tile_ == &it->second) last_tile_ = nullptr;
  deferred_.erase(it);
}

void Replication::forget_deferred() {
  deferred_.clear();
  deferred_vertices_ = 0;
  last_tile_ = nullptr;
}

void Replication::clear_interest(VertexGrid& grid) {
  flush_deferred(grid);
  has_interest_ = false;
}

void Replication::flush_deferred(VertexGrid& grid) {
  std::vector<std::uint64_t> keys;
  keys.reserve(deferred_.size());
  for (const auto& [key, tile] : deferred_) keys.push_back(key);
  std::sort(keys.begin(), keys.end());
  for (const std::uint64_t key : keys) merge_tile(grid, deferred_.at(key));
  forget_deferred();
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
  forget_deferred();
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

// Kept: the merge window (claims of the frame whose lists may still arrive, as (vertex,
// source) sorted by vertex; window_ so deferred slots compare windows as before), the interest
// box and the deferred records (tiles in key order, used slots in slot order). Not kept:
// last_tile_ (a lookup cache, rebuilt on the next deferral).
void Replication::save_state(core::StateWriter& w) const {
  w.begin("scm_replication", 1);
  w.io(source_id_);
  w.io(window_);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> claims;
  claims.reserve(claims_.size());
  claims_.for_each([&](std::uint64_t key, std::int32_t index) {
    claims.emplace_back(key, claim_source_[static_cast<std::size_t>(index)]);
  });
  // By (i, j) (the key's unsigned order would put negative indices last; either is stable).
  std::sort(claims.begin(), claims.end(), [](const auto& a, const auto& b) {
    const std::int32_t ai = key_i(a.first), bi = key_i(b.first);
    return ai != bi ? ai < bi : key_j(a.first) < key_j(b.first);
  });
  w.io(static_cast<std::uint64_t>(claims.size()));
  for (const auto& [key, source] : claims) {
    w.io(key_i(key));
    w.io(key_j(key));
    w.io(source);
  }
  w.io(has_interest_);
  w.io(interest_.i_lo);
  w.io(interest_.i_hi);
  w.io(interest_.j_lo);
  w.io(interest_.j_hi);
  std::vector<std::uint64_t> keys;
  keys.reserve(deferred_.size());
  for (const auto& [key, tile] : deferred_) keys.push_back(key);
  std::sort(keys.begin(), keys.end());
  w.io(static_cast<std::uint64_t>(keys.size()));
  for (const std::uint64_t key : keys) {
    const DeferredTile& tile = deferred_.at(key);
    w.io(key_i(key));
    w.io(key_j(key));
    w.io(static_cast<std::uint32_t>(tile.used()));
    tile.for_each_used([&](std::size_t s, const DeferredSlot& slot) {
      w.io(static_cast<std::uint16_t>(s));  // the vertex follows from the tile and the slot
      w.io(slot.change.level_m);
      w.io(slot.change.level_initial_m);
      w.io(slot.change.sinkage_plastic_m);
      w.io(slot.change.sigma_yield_pa);
      w.io(slot.source);
      w.io(slot.window);
    });
  }
  w.end();
}

void Replication::load_state(core::StateReader& r, const VertexGrid& grid) {
  r.begin("scm_replication", 1);
  r.io(source_id_);
  r.io(window_);
  claims_.clear();
  claim_source_.clear();
  const auto claims = r.get<std::uint64_t>();
  for (std::uint64_t k = 0; k < claims; ++k) {
    const auto i = r.get<std::int32_t>();
    const auto j = r.get<std::int32_t>();
    const auto source = r.get<std::uint32_t>();
    const auto next = static_cast<std::int32_t>(claim_source_.size());
    if (claims_.insert(vertex_key(i, j), next) != next) {
      r.fail("vertex (" + std::to_string(i) + ", " + std::to_string(j) +
             ") is claimed twice: the state is damaged");
    }
    claim_source_.push_back(source);
  }
  r.io(has_interest_);
  r.io(interest_.i_lo);
  r.io(interest_.i_hi);
  r.io(interest_.j_lo);
  r.io(interest_.j_hi);
  forget_deferred();
  const auto tiles = r.get<std::uint64_t>();
  for (std::uint64_t t = 0; t < tiles; ++t) {
    const auto ti = r.get<std::int32_t>();
    const auto tj = r.get<std::int32_t>();
    const auto used = r.get<std::uint32_t>();
    const std::uint64_t key = vertex_key(ti, tj);
    const std::string where = "deferred tile (" + std::to_string(ti) + ", " + std::to_string(tj) + ")";
    if (deferred_.count(key) > 0) r.fail(where + " appears twice: the state is damaged");
    if (used == 0 || used > static_cast<std::uint32_t>(kTileSize * kTileSize)) {
      r.fail(where + " holds " + std::to_string(used) + " records: the state is damaged");
    }
    DeferredTile& tile = deferred_[key];
    tile.where.assign(static_cast<std::size_t>(kTileSize * kTileSize), 0);
    tile.slots.reserve(used);
    deferred_vertices_ += used;
    for (std::uint32_t u = 0; u < used; ++u) {
      const auto s = r.get<std::uint16_t>();
      if (s >= tile.where.size() || tile.where[s] != 0) {
        r.fail(where + ": slot " + std::to_string(s) + " is out of range or repeated");
      }
      DeferredSlot& slot = tile.slots.emplace_back();
      tile.where[s] = static_cast<std::uint16_t>(tile.slots.size());
      slot.change.i = ti * kTileSize + (s >> kTileShift);
      slot.change.j = tj * kTileSize + (s & (kTileSize - 1));
      r.io(slot.change.level_m);
      r.io(slot.change.level_initial_m);
      r.io(slot.change.sinkage_plastic_m);
      r.io(slot.change.sigma_yield_pa);
      r.io(slot.source);
      r.io(slot.window);
      if (!grid.in_area(slot.change.i, slot.change.j)) {
        r.fail(where + ": vertex (" + std::to_string(slot.change.i) + ", " +
               std::to_string(slot.change.j) + ") is outside the soil's area");
      }
      if (slot.window == 0 || slot.window > window_) {
        r.fail(where + ": a record of merge window " + std::to_string(slot.window) +
               " (the state is at window " + std::to_string(window_) + ")");
      }
    }
  }
  r.end();
}

}  // namespace syndds::scm
