#pragma once
// What a scenario's height-map block says (docs/scenario.md): the image file and where it lies.
// Plain data read without decoding the image; HeightmapTerrain (heightmap_terrain.hpp) loads
// the image when a process builds the terrain.
#include <cstdint>
#include <string>

#include "core/math.hpp"
#include "core/yaml.hpp"

namespace syndds::terrain {

struct HeightmapSpec {
  std::string image_file;
  // FNV-1a 64 of the image's bytes as the run's fingerprint has them (0: not checked): the
  // terrain is built from one read of the file whose bytes must hash to this.
  std::uint64_t image_hash = 0;
  double size_x_m = 0.0;
  double size_y_m = 0.0;
  double min_height_m = 0.0;
  double max_height_m = 0.0;
  double friction = 0.8;
  Vec2 centre_m = Vec2::Zero();
};

/// Reads a height-map block:
///   image: hills.png        # relative to base_dir unless absolute
///   size_m: [200, 200]      # x, y
///   height_range_m: [0, 8]  # grey 0 and grey max
///   friction: 0.8           # optional
///   centre_m: [0, 0]        # optional
HeightmapSpec parse_heightmap_spec(const YamlNode& node, const std::string& base_dir);

}  // namespace syndds::terrain
