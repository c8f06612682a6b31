// The world half of scenario.hpp: what needs the terrain built (library syndds_scenario).
#include <cmath>

#include "scenario/scenario.hpp"
#include "scm/scm_terrain.hpp"
#include "terrain/heightmap_terrain.hpp"

namespace syndds::scenario {

std::shared_ptr<const terrain::TerrainSurface> make_terrain(const TerrainConfig& t) {
  if (t.type == "scm") return std::make_shared<scm::ScmTerrain>(t.scm);
  if (t.type == "heightmap") return std::make_shared<terrain::HeightmapTerrain>(t.heightmap);
  return std::make_shared<terrain::FlatTerrain>(t.height_m, t.friction);
}

void place_obstacles(Scenario& s) {
  bool any = false;
  for (const auto& o : s.obstacles) any = any || std::isnan(o.pose.position.z());
  if (!any) return;
  const auto ground = make_terrain(s.terrain);
  for (auto& o : s.obstacles) {
    if (std::isnan(o.pose.position.z())) {
      o.pose.position.z() = ground->height(o.pose.position.x(), o.pose.position.y()) + o.size.z();
    }
  }
}

Scenario load_scenario(const std::string& file, const Overrides& overrides,
                       const std::string& config_dir) {
  auto s = load_scenario_config(file, overrides, config_dir);
  place_obstacles(s);
  return s;
}

Scenario parse_scenario(const YamlNode& root, const std::string& text, const Overrides& overrides,
                        const std::string& config_dir) {
  auto s = parse_scenario_config(root, text, overrides, config_dir);
  place_obstacles(s);
  return s;
}

}  // namespace syndds::scenario
