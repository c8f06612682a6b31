#include "terrain/heightmap_spec.hpp"

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
  if (sz[0] <= 0 || sz[1] <= 0) size.fail("sizes must be positive");
  s.size_x_m = sz[0];
  s.size_y_m = sz[1];
  const YamlNode range = m.required("height_range_m");
  const auto hr = range.as_doubles(2);
  if (hr[1] < hr[0]) range.fail("[min, max] with max >= min");
  s.min_height_m = hr[0];
  s.max_height_m = hr[1];
  s.friction = m.number("friction", 0.8, 0.01, 3.0);
  if (auto c = m.optional("centre_m")) {
    const auto v = c->as_doubles(2);
    s.centre_m = Vec2(v[0], v[1]);
  }
  m.finish();
  return s;
}

}  // namespace syndds::terrain
