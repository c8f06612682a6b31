#include "terrain/heightmap_spec.hpp"

#include <cmath>
#include <filesystem>

namespace syndds::terrain {

HeightmapSpec parse_heightmap_spec(const YamlNode& node, const std::string& base_dir) {
  MapReader m(node);
  HeightmapSpec s;
  const YamlNode image = m.required("image");
  std::filesystem::path file(image.as_string());
  if (file.is_relative()) file = std::filesystem::path(base_dir) / file;
  if (!std::filesystem::exists(file)) image.fail("height-map image not found: " + file.string());
  s.image_file = file.string();
  const YamlNode size = m.required("size_m");
  const auto sz = size.as_doubles(2);
  // Within the renderers' float precision, like every other position (docs/scenario.md).
  if (!(sz[0] > 0 && sz[1] > 0 && sz[0] <= 2e5 && sz[1] <= 2e5)) {
    size.fail("sizes must be in (0, 2e5] m");
  }
  s.size_x_m = sz[0];
  s.size_y_m = sz[1];
  const YamlNode range = m.required("height_range_m");
  const auto hr = range.as_doubles(2);
  if (hr[1] < hr[0]) range.fail("[min, max] with max >= min");
  if (hr[0] < -1e4 || hr[1] > 1e4) range.fail("heights must be in [-1e4, 1e4] m");
  s.min_height_m = hr[0];
  s.max_height_m = hr[1];
  s.friction = m.number("friction", 0.8, 0.01, 3.0);
  if (auto c = m.optional("centre_m")) {
    const auto v = c->as_doubles(2);
    if (std::abs(v[0]) > 1e5 || std::abs(v[1]) > 1e5) c->fail("coordinates must be in [-1e5, 1e5] m");
    s.centre_m = Vec2(v[0], v[1]);
  }
  m.finish();
  return s;
}

}  // namespace syndds::terrain
