#pragma once
// Static obstacles of a scenario (rocks, trees, bushes) as simple shapes. Shared by the
// vehicle dynamics (collisions), the sensors (rendering) and the metrics (obstacles hit).
#include <string>
#include <vector>

#include "core/math.hpp"

namespace syndds::world {

enum class ShapeKind { box, sphere, cylinder };

struct Obstacle {
  std::string id;                 // unique within the scenario, e.g. "rock3"
  std::string label;              // what it is: rock, tree, bush, wall, ...
  ShapeKind shape = ShapeKind::box;
  Pose pose;                      // centre of the shape; a cylinder's axis is its local z
  Vec3 size = Vec3::Ones();       // box: half extents; sphere: (radius, -, -);
                                  // cylinder: (radius, -, half height)
};

using Obstacles = std::vector<Obstacle>;

}  // namespace syndds::world
