#pragma once
// What a viewer needs to draw a scenario's world, as one JSON document (scene.json in the run
// directory, /api/scene from syndds_viewer): the terrain around the action (a height grid),
// the deformable soil's grid, obstacles, vehicles with their chassis and wheel geometry and
// colours (the cameras' palette), and each vehicle's planned path. Everything is derived from
// the scenario alone, so the same scenario always gives the same bytes. Format: docs/viewer.md.
#include <nlohmann/json.hpp>

#include "scenario/scenario.hpp"

namespace syndds::viewer {

/// Bumped when a field changes meaning; the page refuses a scene of another format.
inline constexpr int kSceneFormat = 1;
/// At most this many samples along each side of the terrain height grid.
inline constexpr int kMaxTerrainSamples = 257;

/// The region a viewer shows: every start, waypoint and obstacle (and the soil patch when it
/// is not larger than the world around them) with a margin, inside the scenario's world box.
struct ViewBox {
  double x_min = 0, x_max = 0, y_min = 0, y_max = 0;
};
ViewBox view_box(const scenario::Scenario& s, double margin_m = 20.0);

/// The scene document (obstacles must already be placed: scenario::load_scenario).
nlohmann::json scene_json(const scenario::Scenario& s);

}  // namespace syndds::viewer
