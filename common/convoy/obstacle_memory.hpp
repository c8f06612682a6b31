#pragma once
// A follower's map of the obstacles it has seen (docs/convoy.md, "Obstacles from a camera"):
// range readings across a camera's view (learn::obstacle_ranges' layout: rays at the centres
// of equal slices of the horizontal field of view, left to right, each a distance over the
// range, 1: nothing within it) are placed in the world from the follower's own estimate of
// its position and heading and kept as occupied cells of a grid, so that an obstacle the
// camera has passed is still avoided (KeepOut) while the vehicle drives beside it. A ray that
// reads farther than a cell clears it (what a noisy reading left there is taken back when a
// later one sees through it), and cells farther than `forget_beyond_m` from the follower are
// dropped.
#include <cstdint>
#include <span>
#include <vector>

#include "convoy/follower.hpp"
#include "core/math.hpp"

namespace syndds::convoy {

struct ObstacleMemoryConfig {
  double cell_m = 0.5;
  double forget_beyond_m = 30.0;
  /// A ray clears the cells it passes up to this short of what it reads (the cells of the
  /// obstacle it meets, and those its neighbours mark, stay).
  double clear_margin_m = 1.0;
};

/// One camera's reading: where the camera is on the vehicle and how the rays are laid out.
struct RangeReading {
  std::span<const float> ranges;  // obstacle_ranges' layout
  double hfov_rad = 0.0;
  double range_m = 0.0;
  double camera_ahead_m = 0.0;  // ahead of the reference point, on the vehicle's axis
};

class ObstacleMemory {
 public:
  explicit ObstacleMemory(ObstacleMemoryConfig config = {}) : config_(config) {}

  /// Adds a reading taken at the follower's estimated `position` and heading `yaw_rad`.
  /// std::invalid_argument for an empty reading or a field of view or range <= 0.
  void observe(const Vec2& position, double yaw_rad, const RangeReading& reading);
  /// The occupied cells as circles (centre, half the cell's diagonal), in key order.
  std::vector<KeepOut::Circle> circles() const;
  std::size_t size() const { return cells_.size(); }
  void clear() { cells_.clear(); }

  /// Checkpoints: the occupied cells.
  template <typename Archive>
  void state_io(Archive& a) {
    a.begin("obstacle_memory", 1);
    a.io(cells_);
    a.end();
  }

 private:
  std::int64_t key(const Vec2& p) const;
  Vec2 centre(std::int64_t key) const;

  ObstacleMemoryConfig config_;
  std::vector<std::int64_t> cells_;  // sorted keys of the occupied cells
};

}  // namespace syndds::convoy
