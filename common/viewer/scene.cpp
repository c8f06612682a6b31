#include "viewer/scene.hpp"

#include <algorithm>
#include <cmath>

#include "sensors/scene.hpp"

namespace syndds::viewer {
namespace {

nlohmann::json vec(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
nlohmann::json quat(const Quat& q) { return {q.w(), q.x(), q.y(), q.z()}; }
// Colours to 3 decimals: the float values would print as 0.41999998688697815.
nlohmann::json rgb(const sensors::Rgb& c) {
  const auto r3 = [](float x) { return std::round(static_cast<double>(x) * 1000.0) / 1000.0; };
  return {r3(c.r), r3(c.g), r3(c.b)};
}

const char* shape_name(world::ShapeKind k) {
  switch (k) {
    case world::ShapeKind::box: return "box";
    case world::ShapeKind::sphere: return "sphere";
    case world::ShapeKind::cylinder: return "cylinder";
  }
  return "box";
}

struct Bounds {
  double x_min = INFINITY, x_max = -INFINITY, y_min = INFINITY, y_max = -INFINITY;
  void add(double x, double y, double r = 0.0) {
    x_min = std::min(x_min, x - r);
    x_max = std::max(x_max, x + r);
    y_min = std::min(y_min, y - r);
    y_max = std::max(y_max, y + r);
  }
  bool empty() const { return x_min > x_max; }
};

nlohmann::json terrain_json(const scenario::Scenario& s, const ViewBox& box) {
  const auto surface = scenario::make_terrain(s.terrain);
  const bool flat = s.terrain.type != "heightmap";
  const int nx = flat ? 2 : kMaxTerrainSamples;
  const int ny = flat ? 2 : kMaxTerrainSamples;
  std::vector<double> heights;
  heights.reserve(static_cast<std::size_t>(nx) * ny);
  for (int r = 0; r < ny; ++r) {
    const double y = box.y_min + (box.y_max - box.y_min) * r / (ny - 1);
    for (int c = 0; c < nx; ++c) {
      const double x = box.x_min + (box.x_max - box.x_min) * c / (nx - 1);
      heights.push_back(surface->height(x, y));
    }
  }
  return {{"type", s.terrain.type},
          {"x_min", box.x_min},
          {"x_max", box.x_max},
          {"y_min", box.y_min},
          {"y_max", box.y_max},
          {"nx", nx},
          {"ny", ny},
          {"heights", heights}};
}

}  // namespace

ViewBox view_box(const scenario::Scenario& s, double margin_m) {
  Bounds b;
  for (const auto& v : s.vehicles) {
    b.add(v.start.position.x(), v.start.position.y());
    for (const auto& w : v.controller.waypoints) b.add(w.x(), w.y());
  }
  for (const auto& o : s.obstacles) b.add(o.pose.position.x(), o.pose.position.y(), o.size.x());
  if (b.empty()) b.add(0.0, 0.0);
  if (s.terrain.deformable()) {
    // The soil patch, unless it is far larger than the action (then only the action's part).
    const auto& g = s.terrain.scm.grid;
    const double side = std::max(b.x_max - b.x_min, b.y_max - b.y_min) + 2 * margin_m;
    if (std::max(g.x_max_m - g.x_min_m, g.y_max_m - g.y_min_m) <= 2 * side) {
      b.add(g.x_min_m, g.y_min_m);
      b.add(g.x_max_m, g.y_max_m);
    }
  }
  ViewBox box{b.x_min - margin_m, b.x_max + margin_m, b.y_min - margin_m, b.y_max + margin_m};
  box.x_min = std::max(box.x_min, s.world.x_min_m);
  box.x_max = std::min(box.x_max, s.world.x_max_m);
  box.y_min = std::max(box.y_min, s.world.y_min_m);
  box.y_max = std::min(box.y_max, s.world.y_max_m);
  return box;
}

nlohmann::json scene_json(const scenario::Scenario& s) {
  const ViewBox box = view_box(s);
  nlohmann::json scene = {{"format", kSceneFormat},
                          {"name", s.name},
                          {"heartbeat_s", s.time.heartbeat_s},
                          {"end_time_s", s.time.end_time_s},
                          {"final_frame", s.time.final_frame()},
                          {"terrain", terrain_json(s, box)}};
  if (s.terrain.deformable()) {
    const auto& g = s.terrain.scm.grid;
    const double d = g.spacing_m;
    scene["soil"] = {{"spacing_m", d},
                     {"i_min", static_cast<std::int64_t>(std::ceil(g.x_min_m / d - 1e-9))},
                     {"i_max", static_cast<std::int64_t>(std::floor(g.x_max_m / d + 1e-9))},
                     {"j_min", static_cast<std::int64_t>(std::ceil(g.y_min_m / d - 1e-9))},
                     {"j_max", static_cast<std::int64_t>(std::floor(g.y_max_m / d + 1e-9))},
                     {"base_height_m", g.base_height_m}};
  } else {
    scene["soil"] = nullptr;
  }
  nlohmann::json obstacles = nlohmann::json::array();
  for (const auto& o : s.obstacles) {
    obstacles.push_back({{"id", o.id},
                         {"label", o.label},
                         {"shape", shape_name(o.shape)},
                         {"position", vec(o.pose.position)},
                         {"orientation", quat(o.pose.orientation)},
                         {"size", vec(o.size)},
                         {"colour", rgb(sensors::obstacle_colour(o.label))}});
  }
  scene["obstacles"] = obstacles;
  nlohmann::json vehicles = nlohmann::json::array();
  for (std::size_t k = 0; k < s.vehicles.size(); ++k) {
    const auto& v = s.vehicles[k];
    const auto shape = sensors::vehicle_shape(v.params, sensors::vehicle_palette(k));
    nlohmann::json wheels = nlohmann::json::array();
    for (const auto& w : shape.wheel_positions_m) wheels.push_back(vec(w));
    // The boxes the sensors draw the body with (hull, deck, cabin): the page draws the same,
    // and fits the body mesh to their bounding box as the sensors do.
    nlohmann::json body = nlohmann::json::array();
    for (const auto& b : sensors::vehicle_body_boxes(shape)) {
      body.push_back({{"centre", vec(b.centre)}, {"half_extents", vec(b.half_extents)}});
    }
    nlohmann::json path = nlohmann::json::array();
    for (const auto& w : v.controller.waypoints) path.push_back({w.x(), w.y()});
    vehicles.push_back({{"id", v.id},
                        {"model", v.model},
                        {"dynamics", v.dynamics},
                        {"colour", rgb(shape.body_colour)},
                        {"chassis_half_extents", vec(shape.half_extents_m)},
                        {"chassis_centre", vec(shape.box_centre_m)},
                        {"wheel_radius", shape.wheel_radius_m},
                        {"wheel_width", shape.wheel_width_m},
                        {"wheel_positions", wheels},
                        {"body_boxes", body},
                        {"controller", v.controller.type},
                        {"follows", v.controller.follows() ? v.controller.convoy.leader : ""},
                        {"path", path},
                        {"path_closed", v.controller.closed},
                        {"start", vec(v.start.position)}});
  }
  scene["vehicles"] = vehicles;
  return scene;
}

}  // namespace syndds::viewer
