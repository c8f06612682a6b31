#pragma once
// Terrain images: a 16-bit grey height map and a 16-bit rut-depth map of an ScmTerrain, plus a
// JSON side file with the mapping from pixel value to metres.
//
// Pixel (row, col) shows vertex (i, j) = (region.i_min + col, region.j_max - row): x grows to
// the right, y grows upwards (north up). Values map linearly:
//   height_m    = height_min_m + value * height_m_per_count
//   rut_depth_m = value * rut_depth_m_per_count,   rut depth = max(0, base height - height)
//
// Beside these data images, a picture for people: <prefix>_rut_colour.png, 8-bit RGB, the rut
// depth through the viridis colour map (0 dark violet, the deepest rut yellow), each vertex a
// square of `colour_scale_px` pixels, north up, with x and y axes in metres, a scale bar and a
// colour bar labelled in metres.
#include <cstdint>
#include <optional>
#include <string>

#include "scm/scm_terrain.hpp"

namespace syndds::scm {

struct ImageRegion {
  std::int32_t i_min = 0, i_max = 0, j_min = 0, j_max = 0;  // inclusive vertex ranges
};

struct TerrainImageInfo {
  std::string height_png;
  std::string rut_png;
  std::string json;
  ImageRegion region;
  int width_px = 0;
  int height_px = 0;
  double height_min_m = 0.0;
  double height_m_per_count = 0.0;
  double rut_depth_m_per_count = 0.0;
  double rut_depth_max_m = 0.0;
  // The colour picture: its file, size, where the map is (vertex (i_min, j_max) fills the
  // square at map_left_px, map_top_px) and where the colour bar is (bottom = depth 0,
  // top = rut_depth_max_m).
  std::string rut_colour_png;
  int colour_width_px = 0, colour_height_px = 0;
  int colour_scale_px = 1;  // image pixels per vertex along each axis
  int map_left_px = 0, map_top_px = 0;
  int bar_left_px = 0, bar_top_px = 0, bar_width_px = 0, bar_height_px = 0;
};

/// The stored vertices' bounding box grown by `margin` vertices and clipped to the area
/// (nullopt if nothing is stored).
std::optional<ImageRegion> deformed_region(const ScmTerrain& terrain, std::int32_t margin = 10);

/// Writes <prefix>_height.png, <prefix>_rut.png, <prefix>_rut_colour.png and
/// <prefix>_images.json, each replaced
/// atomically (throws record::WriteError naming the file if one cannot be written). Without `region`, deformed_region() is used,
/// or a single vertex at the area's centre when nothing deformed.
TerrainImageInfo write_terrain_images(const ScmTerrain& terrain, const std::string& prefix,
                                      std::optional<ImageRegion> region = std::nullopt);

}  // namespace syndds::scm
