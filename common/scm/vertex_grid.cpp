#include "scm/vertex_grid.hpp"

#include <cmath>
#include <limits>

namespace syndds::scm {

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
