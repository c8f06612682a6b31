#pragma once
// A scenario with its world resolved: the configuration (scenario_config.hpp) plus what needs
// the terrain built (obstacles resting on the ground). For the processes that simulate; the
// coordinator and syndds_plan use load_scenario_config, which builds nothing.
#include <memory>
#include <string>

// The simulation side of what the config structs name (kept here for the agents that use them).
#include "convoy/v2v.hpp"
#include "scenario/scenario_config.hpp"
#include "sensors/rig.hpp"
#include "terrain/heightmap_terrain.hpp"
#include "terrain/terrain.hpp"

namespace syndds::scenario {

/// The terrain surface a terrain block describes (for scm: a fresh, undeformed ScmTerrain).
std::shared_ptr<const terrain::TerrainSurface> make_terrain(const TerrainConfig& terrain);

/// Sets the z of the obstacles given without one: a sphere on its lowest point, a box or a
/// cylinder on its base, on the undeformed terrain.
void place_obstacles(Scenario& s);

/// load_scenario_config, then place_obstacles.
Scenario load_scenario(const std::string& file, const Overrides& overrides = {},
                       const std::string& config_dir = default_config_dir());
Scenario parse_scenario(const YamlNode& root, const std::string& text, const Overrides& overrides,
                        const std::string& config_dir);

}  // namespace syndds::scenario
