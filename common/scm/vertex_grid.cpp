#include "scm/vertex_grid.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <string>

#include "core/state_io.hpp"

namespace syndds::scm {
namespace {

// Flags of a vertex in a checkpoint: which fields follow (a field equal, bit for bit, to the
// value of a fresh record is left out, so a rut vertex costs 33 bytes, a rim vertex 25).
enum StateFlag : std::uint8_t {
  kDirty = 1,            // in the dirty list (a pending outgoing change)
  kContact = 2,          // in contact in the last step: shear_x, shear_y, sigma follow
  kLevelInitial = 4,     // level_initial differs from the base height
  kSinkagePlastic = 8,   // sinkage_plastic is not +0
  kSigmaYield = 16,      // sigma_yield is not +0
  kAllFlags = 31,
};

bool same_bits(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

}  // namespace

VertexChange to_change(const VertexRecord& r) {
  VertexChange c;
  c.i = r.i;
  c.j = r.j;
  c.level_m = r.level;
  c.level_initial_m = r.level_initial;
  c.sinkage_plastic_m = r.sinkage_plastic;
  c.sigma_yield_pa = r.sigma_yield;
  return c;
}

VertexGrid::VertexGrid(const GridParams& grid, std::shared_ptr<const terrain::TerrainSurface> base)
    : base_(std::move(base)), base_height_m_(grid.base_height_m), delta_(grid.spacing_m) {
  cell_area_ = delta_ * delta_;
  i_min_ = static_cast<std::int32_t>(std::ceil(grid.x_min_m / delta_ - 1e-9));
  i_max_ = static_cast<std::int32_t>(std::floor(grid.x_max_m / delta_ + 1e-9));
  j_min_ = static_cast<std::int32_t>(std::ceil(grid.y_min_m / delta_ - 1e-9));
  j_max_ = static_cast<std::int32_t>(std::floor(grid.y_max_m / delta_ + 1e-9));
  level_bound_ = base_ ? std::numeric_limits<double>::infinity() : base_height_m_;
}

std::int32_t VertexGrid::get_or_insert(std::int32_t i, std::int32_t j) {
  const auto next = static_cast<std::int32_t>(records_.size());
  const std::int32_t r = index_.insert(vertex_key(i, j), next);
  if (r == next) {
    VertexRecord rec;
    rec.i = i;
    rec.j = j;
    rec.level = rec.level_initial = base_height(i, j);
    records_.push_back(rec);
    mark_dirty(r);  // a new record is new shared state: every copy must hold it
  }
  return r;
}

std::int32_t VertexGrid::get_or_insert_blank(std::int32_t i, std::int32_t j) {
  const auto next = static_cast<std::int32_t>(records_.size());
  const std::int32_t r = index_.insert(vertex_key(i, j), next);
  if (r == next) {
    VertexRecord rec;
    rec.i = i;
    rec.j = j;
    records_.push_back(rec);
  }
  return r;
}

void VertexGrid::assign(VertexRecord& r, const VertexChange& c) {
  r.level = c.level_m;
  r.level_initial = c.level_initial_m;
  r.sinkage_plastic = c.sinkage_plastic_m;
  r.sigma_yield = c.sigma_yield_pa;
  note_level(r.level);
  note_level(r.level_initial - r.sinkage_plastic);
}

void VertexGrid::clear() {
  index_.clear();
  records_.clear();
  dirty_.clear();
  level_bound_ = base_ ? std::numeric_limits<double>::infinity() : base_height_m_;
}

}  // namespace syndds::scm

namespace syndds::scm {

// What a record holds and whether it is kept:
//  - the shared state (level, level_initial, sinkage_plastic, sigma_yield): all of it, the
//    last three only where they differ from a fresh record (base height, 0, 0);
//  - the contact state (shear_x/y, sigma) only for vertices in contact in the last step: the
//    law reads the shear only after an unbroken contact (contact_step == step - 1) and
//    vertex_pressure the stress only then, so older values never reach a result. contact_step
//    itself is stored as that flag and restored relative to `last_step`;
//  - step_plastic_flow is not kept: the law writes it before bulldozing reads it, every step;
//  - dirty: kept (the vertex is in the next take_local_changes list). The dirty list is rebuilt
//    in (i, j) order; replication sorts what it takes, so the marking order never shows;
//  - the record order (insertion order) is not kept: records are written sorted by (i, j) and
//    nothing that reaches a result depends on their order (snapshot and hash sort them).
// The level bound is kept as is: it can lie above every stored level (levels only fall after
// it was raised, deferred records raise it) and it decides which bodies touch the soil.
void VertexGrid::save_state(core::StateWriter& w, std::int64_t last_step) const {
  w.begin("scm_grid", 1);
  w.io(level_bound_);
  std::vector<std::int32_t> order(records_.size());
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = static_cast<std::int32_t>(k);
  std::sort(order.begin(), order.end(), [&](std::int32_t a, std::int32_t b) {
    const VertexRecord& ra = records_[static_cast<std::size_t>(a)];
    const VertexRecord& rb = records_[static_cast<std::size_t>(b)];
    return ra.i != rb.i ? ra.i < rb.i : ra.j < rb.j;
  });
  w.io(static_cast<std::uint64_t>(order.size()));
  for (const std::int32_t k : order) {
    const VertexRecord& r = records_[static_cast<std::size_t>(k)];
    std::uint8_t flags = 0;
    if (r.dirty) flags |= kDirty;
    if (r.contact_step == last_step) flags |= kContact;
    if (!same_bits(r.level_initial, base_height(r.i, r.j))) flags |= kLevelInitial;
    if (!same_bits(r.sinkage_plastic, 0.0)) flags |= kSinkagePlastic;
    if (!same_bits(r.sigma_yield, 0.0)) flags |= kSigmaYield;
    w.io(r.i);
    w.io(r.j);
    w.io(flags);
    w.io(r.level);
    if (flags & kLevelInitial) w.io(r.level_initial);
    if (flags & kSinkagePlastic) w.io(r.sinkage_plastic);
    if (flags & kSigmaYield) w.io(r.sigma_yield);
    if (flags & kContact) {
      w.io(r.shear_x);
      w.io(r.shear_y);
      w.io(r.sigma);
    }
  }
  w.end();
}

void VertexGrid::load_state(core::StateReader& r, std::int64_t last_step) {
  r.begin("scm_grid", 1);
  clear();
  const auto bound = r.get<double>();
  const auto n = r.get<std::uint64_t>();
  bool first = true;
  std::int32_t prev_i = 0, prev_j = 0;
  for (std::uint64_t k = 0; k < n; ++k) {
    const auto i = r.get<std::int32_t>();
    const auto j = r.get<std::int32_t>();
    const auto flags = r.get<std::uint8_t>();
    const std::string where = "vertex (" + std::to_string(i) + ", " + std::to_string(j) + ")";
    if (!in_area(i, j)) r.fail(where + " is outside the soil's area");
    if (!first && !(i > prev_i || (i == prev_i && j > prev_j))) {
      r.fail(where + " is not after the vertex before it: the state is damaged");
    }
    if ((flags & ~kAllFlags) != 0) r.fail(where + " has unknown flags " + std::to_string(flags));
    first = false;
    prev_i = i;
    prev_j = j;
    const std::int32_t index = get_or_insert_blank(i, j);
    VertexRecord& rec = record(index);
    rec.level = r.get<double>();
    rec.level_initial = (flags & kLevelInitial) ? r.get<double>() : base_height(i, j);
    rec.sinkage_plastic = (flags & kSinkagePlastic) ? r.get<double>() : 0.0;
    rec.sigma_yield = (flags & kSigmaYield) ? r.get<double>() : 0.0;
    if (flags & kContact) {
      rec.shear_x = r.get<double>();
      rec.shear_y = r.get<double>();
      rec.sigma = r.get<double>();
      rec.contact_step = last_step;
    }
    if (flags & kDirty) mark_dirty(index);
  }
  level_bound_ = bound;
  r.end();
}

}  // namespace syndds::scm
