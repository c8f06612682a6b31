#pragma once
// Rigid terrain from a height map: a regular grid of heights read from a grey image (8 or 16
// bit, via OpenCV) or given directly. Heights are bilinear between grid vertices; normals come
// from the grid (central differences at the vertices, one-sided at the border, interpolated
// bilinearly and normalised). Outside the map the border heights continue (constant across
// the border, so the normal there has no slope in that direction).
//
// Image convention (as Chrono's height-map patches): the image covers size_x_m x size_y_m
// centred on centre_m; column 0 is the west edge (min x), row 0 the north edge (max y); pixel
// centres are the grid vertices, so a W x H image has spacing size_x / (W - 1). Grey value g
// maps to min_height + (max_height - min_height) g / g_max (g_max 255 or 65535).
#include <string>
#include <vector>

#include "core/math.hpp"
#include "terrain/heightmap_spec.hpp"
#include "terrain/terrain.hpp"

namespace syndds::terrain {

class HeightmapTerrain final : public TerrainSurface {
 public:
  /// Loads the image; throws ConfigError naming the file if it cannot be read or is not grey.
  explicit HeightmapTerrain(const HeightmapSpec& spec);
  /// Heights given directly: heights[j * columns + i] at x = x_min + i dx, y = y_min + j dy
  /// (j = 0 is the south edge). Needs at least 2 x 2 vertices.
  HeightmapTerrain(int columns, int rows, std::vector<double> heights, double size_x_m,
                   double size_y_m, double friction = 0.8, const Vec2& centre_m = Vec2::Zero());

  double height(double x, double y) const override;
  Vec3 normal(double x, double y) const override;
  double friction(double, double) const override { return friction_; }

  int columns() const { return nx_; }
  int rows() const { return ny_; }
  double spacing_x_m() const { return dx_; }
  double spacing_y_m() const { return dy_; }
  /// World position of vertex (i, j), j = 0 the south edge.
  Vec2 vertex_position(int i, int j) const;
  double vertex_height(int i, int j) const { return h_[index(i, j)]; }

 private:
  void init(double size_x_m, double size_y_m, const Vec2& centre_m);
  std::size_t index(int i, int j) const {
    return static_cast<std::size_t>(j) * static_cast<std::size_t>(nx_) +
           static_cast<std::size_t>(i);
  }
  /// Cell and fractions for a world point (clamped to the map).
  void locate(double x, double y, int& i, int& j, double& tx, double& ty) const;

  int nx_ = 0, ny_ = 0;
  double dx_ = 0.0, dy_ = 0.0;
  double x_min_ = 0.0, y_min_ = 0.0;
  double friction_ = 0.8;
  std::vector<double> h_;
  std::vector<double> gx_, gy_;  // dh/dx, dh/dy at the vertices
};

}  // namespace syndds::terrain
