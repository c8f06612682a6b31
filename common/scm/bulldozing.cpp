#include "scm/bulldozing.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace syndds::scm {

std::size_t Bulldozer::run(VertexGrid& grid, const ContactPatches& s) {
  const std::size_t patches = s.patches();
  if (patches == 0) return 0;
  // All patches share one erosion domain (as in Chrono) when their common window is of
  // reasonable size; otherwise (bodies far apart) each patch is bulldozed in its own window.
  const std::int32_t margin = params_.propagations + 2;
  auto window_of = [&](std::size_t p0, std::size_t p1) {
    std::int32_t i0 = std::numeric_limits<std::int32_t>::max(), j0 = i0;
    std::int32_t i1 = std::numeric_limits<std::int32_t>::min(), j1 = i1;
    for (auto q = s.patch_start[p0]; q < s.patch_start[p1]; ++q) {
      const auto c = static_cast<std::size_t>(s.patch_members[static_cast<std::size_t>(q)]);
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.contacts[c])];
      i0 = std::min(i0, v.i);
      i1 = std::max(i1, v.i);
      j0 = std::min(j0, v.j);
      j1 = std::max(j1, v.j);
    }
    return std::array<std::int64_t, 4>{
        static_cast<std::int64_t>(i0) - margin, static_cast<std::int64_t>(i1) + margin,
        static_cast<std::int64_t>(j0) - margin, static_cast<std::int64_t>(j1) + margin};
  };
  const auto all = window_of(0, patches);
  const std::int64_t cells = (all[1] - all[0] + 1) * (all[3] - all[2] + 1);
  if (cells <= (std::int64_t{1} << 22)) return run_window(grid, s, 0, patches, all);
  std::size_t domain = 0;
  for (std::size_t p = 0; p < patches; ++p) {
    domain += run_window(grid, s, p, p + 1, window_of(p, p + 1));
  }
  return domain;
}

std::size_t Bulldozer::run_window(VertexGrid& grid, const ContactPatches& s, std::size_t p_begin,
                                  std::size_t p_end, const std::array<std::int64_t, 4>& window) {
  const BulldozingParams& bp = params_;
  // Dense window over the patches (+ margin): cell = -2 not free (outside the area or under a
  // body), -1 free, >= 0 index into bd_ (the erosion domain).
  const std::int64_t wi0 = window[0], wj0 = window[2];
  const auto ww = static_cast<std::int32_t>(window[1] - window[0] + 1);
  const auto wh = static_cast<std::int32_t>(window[3] - window[2] + 1);
  cells_.assign(static_cast<std::size_t>(ww) * static_cast<std::size_t>(wh), -2);
  auto cell_of = [&](std::int32_t i, std::int32_t j) {
    return static_cast<std::size_t>((j - wj0) * ww + (i - wi0));
  };
  {  // free inside the area
    const std::int64_t c0 = std::max<std::int64_t>(0, grid.i_min() - wi0);
    const std::int64_t c1 = std::min<std::int64_t>(ww - 1, grid.i_max() - wi0);
    const std::int64_t r0 = std::max<std::int64_t>(0, grid.j_min() - wj0);
    const std::int64_t r1 = std::min<std::int64_t>(wh - 1, grid.j_max() - wj0);
    for (std::int64_t r = r0; r <= r1; ++r) {
      auto row = cells_.begin() + r * ww;
      std::fill(row + c0, row + c1 + 1, -1);
    }
  }
  for (const StepVertex& v : s.vertices) {  // covered vertices (contacts included)
    if (v.alias >= 0 || v.z_hit == kInf) continue;
    if (v.i >= wi0 && v.i < wi0 + ww && v.j >= wj0 && v.j < wj0 + wh)
      cells_[cell_of(v.i, v.j)] = -2;
  }
  bd_.clear();
  auto add_material = [&](std::int32_t i, std::int32_t j, double amount) {
    const std::int32_t r = grid.get_or_insert(i, j);
    VertexRecord& rec = grid.record(r);
    rec.level += amount;
    rec.level_initial += amount;
    grid.note_level(rec.level);
    grid.note_level(rec.level_initial - rec.sinkage_plastic);
    grid.mark_dirty(r);
  };
  auto add_domain = [&](std::int32_t i, std::int32_t j, std::size_t cell) {
    const auto index = static_cast<std::int32_t>(bd_.size());
    cells_[cell] = index;
    DomainVertex v;
    v.i = i;
    v.j = j;
    bd_.push_back(v);
    return index;
  };

  // (1) Raise the rim of each patch by its share of the patch's plastic flow.
  for (std::size_t p = p_begin; p < p_end; ++p) {
    double flow = 0.0;
    boundary_.clear();
    for (auto q = s.patch_start[p]; q < s.patch_start[p + 1]; ++q) {
      const auto c = static_cast<std::size_t>(s.patch_members[static_cast<std::size_t>(q)]);
      if (!s.loads[c].loaded) continue;
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.contacts[c])];
      flow += grid.record(v.record).step_plastic_flow;
      for (int n = 0; n < 4; ++n) {
        const std::int32_t ni = v.i + kNeighbourDi[n], nj = v.j + kNeighbourDj[n];
        const std::size_t cell = cell_of(ni, nj);
        std::int32_t slot = cells_[cell];
        if (slot == -2) continue;
        if (slot == -1) slot = add_domain(ni, nj, cell);
        auto& bv = bd_[static_cast<std::size_t>(slot)];
        if (bv.patch == static_cast<std::int32_t>(p)) continue;
        bv.patch = static_cast<std::int32_t>(p);
        boundary_.push_back(slot);
      }
    }
    if (boundary_.empty()) continue;  // nowhere to put it: the volume is compacted instead
    const double raise = bp.flow_factor * flow / static_cast<double>(boundary_.size());
    if (raise == 0.0) continue;
    for (const std::int32_t slot : boundary_) {
      const auto& bv = bd_[static_cast<std::size_t>(slot)];
      add_material(bv.i, bv.j, raise);
    }
  }
  const std::size_t rims = bd_.size();
  if (rims == 0 || bp.iterations == 0) return rims;

  // (2) Erosion domain: the rims dilated `propagations` times over free vertices.
  std::size_t front_begin = 0, front_end = rims;
  for (int ring = 0; ring < bp.propagations && front_begin < front_end; ++ring) {
    for (std::size_t f = front_begin; f < front_end; ++f) {
      const std::int32_t i = bd_[f].i, j = bd_[f].j;
      for (int n = 0; n < 4; ++n) {
        const std::int32_t ni = i + kNeighbourDi[n], nj = j + kNeighbourDj[n];
        const std::size_t cell = cell_of(ni, nj);
        if (cells_[cell] == -1) add_domain(ni, nj, cell);
      }
    }
    front_begin = front_end;
    front_end = bd_.size();
  }
  const std::size_t domain = bd_.size();
  for (auto& v : bd_) {
    v.start = grid.level_of(v.i, v.j);
    for (int n = 0; n < 4; ++n) {
      const std::int32_t c = cells_[cell_of(v.i + kNeighbourDi[n], v.j + kNeighbourDj[n])];
      v.neighbour[n] = c >= 0 ? c : -1;
    }
  }

  // (3) Erosion sweeps (Gauss-Seidel in domain order) on cached heights, each pair of
  // 4-neighbours once per sweep (east and north links); stop early once a sweep moves nothing
  // (the remaining sweeps would not either).
  const double limit = grid.spacing() * std::tan(deg_to_rad(bp.erosion_angle_deg));
  for (int iter = 0; iter < bp.iterations; ++iter) {
    bool moved = false;
    for (auto& v : bd_) {
      for (int n = 2; n < 4; ++n) {  // kNeighbour order S, W, E, N
        if (v.neighbour[n] < 0) continue;
        auto& o = bd_[static_cast<std::size_t>(v.neighbour[n])];
        const double dh = (v.start + v.delta) - (o.start + o.delta);
        const double excess = std::abs(dh) - limit;
        if (!(excess > 0.0)) continue;
        const double amount = excess / 4.0;
        if (dh > 0.0) {
          v.delta -= amount;
          o.delta += amount;
        } else {
          o.delta -= amount;
          v.delta += amount;
        }
        moved = true;
      }
    }
    if (!moved) break;
  }

  // (4) Write the moved material back (records only where something changed).
  for (const auto& v : bd_) {
    if (v.delta != 0.0) add_material(v.i, v.j, v.delta);
  }
  return domain;
}

}  // namespace syndds::scm
