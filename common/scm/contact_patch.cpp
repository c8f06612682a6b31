#include "scm/contact_patch.hpp"

#include <cstdlib>

namespace syndds::scm {

void hull_of_cells(std::vector<std::pair<std::int64_t, std::int64_t>>& pts, double& area,
                   double& perimeter) {
  std::sort(pts.begin(), pts.end());
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  const std::int64_t wx = pts.back().first - pts.front().first;
  std::int64_t ymin = pts.front().second, ymax = ymin;
  for (const auto& p : pts) {
    ymin = std::min(ymin, p.second);
    ymax = std::max(ymax, p.second);
  }
  const std::int64_t wy = ymax - ymin;
  std::vector<std::pair<std::int64_t, std::int64_t>> h;
  if (pts.size() >= 3) {
    auto cross = [](const auto& o, const auto& a, const auto& b) {
      return (a.first - o.first) * (b.second - o.second) -
             (a.second - o.second) * (b.first - o.first);
    };
    h.resize(2 * pts.size());
    std::size_t k = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      while (k >= 2 && cross(h[k - 2], h[k - 1], pts[i]) <= 0) --k;
      h[k++] = pts[i];
    }
    for (std::size_t i = pts.size() - 1, t = k + 1; i-- > 0;) {
      while (k >= t && cross(h[k - 2], h[k - 1], pts[i]) <= 0) --k;
      h[k++] = pts[i];
    }
    h.resize(k - 1);
  } else {
    h = pts;
  }
  std::int64_t twice_area = 0;
  double hull_perimeter = 0.0;
  const std::size_t n = h.size();
  if (n >= 3) {
    for (std::size_t i = 0; i < n; ++i) {
      const auto& a = h[i];
      const auto& b = h[(i + 1) % n];
      twice_area += a.first * b.second - b.first * a.second;
      hull_perimeter += std::hypot(static_cast<double>(b.first - a.first),
                                   static_cast<double>(b.second - a.second));
    }
  } else if (n == 2) {
    hull_perimeter = 2.0 * std::hypot(static_cast<double>(h[1].first - h[0].first),
                                      static_cast<double>(h[1].second - h[0].second));
  }
  // Minkowski sum with the unit cell: A + (width_x + width_y) + 1, P + 4.
  area = 0.5 * static_cast<double>(std::llabs(twice_area)) + static_cast<double>(wx + wy) + 1.0;
  perimeter = hull_perimeter + 4.0;
}

void find_patches(ContactPatches& s, double test_height, double delta) {
  const std::size_t nc = s.contacts.size();
  s.contact_patch.assign(nc, -1);
  s.patch_start.clear();
  s.patch_members.clear();
  s.patch_oob.clear();
  s.patch_vertices.clear();
  auto patch_vertex = [&](const StepVertex& v) {
    return v.has_level && v.z_hit < v.surface + test_height;
  };
  for (std::size_t c0 = 0; c0 < nc; ++c0) {
    if (s.contact_patch[c0] >= 0) continue;
    const auto patch = static_cast<std::int32_t>(s.patch_start.size());
    s.patch_start.push_back(static_cast<std::int32_t>(s.patch_members.size()));
    const std::size_t first = s.patch_vertices.size();
    StepVertex& seed = s.vertices[static_cast<std::size_t>(s.contacts[c0])];
    seed.patch = patch;
    s.patch_vertices.push_back(s.contacts[c0]);
    for (std::size_t q = first; q < s.patch_vertices.size(); ++q) {  // breadth-first
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.patch_vertices[q])];
      if (v.contact >= 0) {
        s.contact_patch[static_cast<std::size_t>(v.contact)] = patch;
        s.patch_members.push_back(v.contact);
      }
      for (int n = 0; n < 4; ++n) {
        const std::int32_t at = s.find_vertex(v.i + kNeighbourDi[n], v.j + kNeighbourDj[n]);
        if (at < 0) continue;
        StepVertex& nb = s.vertices[static_cast<std::size_t>(at)];
        if (nb.patch >= 0 || !patch_vertex(nb)) continue;
        nb.patch = patch;
        s.patch_vertices.push_back(at);
      }
    }
    // Only the extreme vertices of each row can be on the convex hull.
    std::int32_t jlo = std::numeric_limits<std::int32_t>::max();
    std::int32_t jhi = std::numeric_limits<std::int32_t>::min();
    for (std::size_t q = first; q < s.patch_vertices.size(); ++q) {
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.patch_vertices[q])];
      jlo = std::min(jlo, v.j);
      jhi = std::max(jhi, v.j);
    }
    const auto rows = static_cast<std::size_t>(jhi - jlo + 1);
    s.row_min.assign(rows, std::numeric_limits<std::int32_t>::max());
    s.row_max.assign(rows, std::numeric_limits<std::int32_t>::min());
    for (std::size_t q = first; q < s.patch_vertices.size(); ++q) {
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.patch_vertices[q])];
      const auto row = static_cast<std::size_t>(v.j - jlo);
      s.row_min[row] = std::min(s.row_min[row], v.i);
      s.row_max[row] = std::max(s.row_max[row], v.i);
    }
    s.hull_points.clear();
    for (std::size_t row = 0; row < rows; ++row) {
      if (s.row_min[row] > s.row_max[row]) continue;
      const std::int64_t j = jlo + static_cast<std::int64_t>(row);
      s.hull_points.emplace_back(s.row_min[row], j);
      if (s.row_max[row] != s.row_min[row]) s.hull_points.emplace_back(s.row_max[row], j);
    }
    double area = 0.0, perimeter = 0.0;
    hull_of_cells(s.hull_points, area, perimeter);
    // 1/b = P / (2 A), with A in delta^2 and P in delta units.
    s.patch_oob.push_back(perimeter / (2.0 * area * delta));
  }
  s.patch_start.push_back(static_cast<std::int32_t>(s.patch_members.size()));
}

}  // namespace syndds::scm
