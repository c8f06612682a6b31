#include "convoy/obstacle_memory.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace syndds::convoy {
namespace {

// Cell indices within +-2^30 cells (the key stays positive); it orders cells by (i, j).
constexpr std::int64_t kOffset = std::int64_t{1} << 30;

}  // namespace

std::int64_t ObstacleMemory::key(const Vec2& p) const {
  const auto i = static_cast<std::int64_t>(std::floor(p.x() / config_.cell_m)) + kOffset;
  const auto j = static_cast<std::int64_t>(std::floor(p.y() / config_.cell_m)) + kOffset;
  return (i << 32) | j;
}

Vec2 ObstacleMemory::centre(std::int64_t key) const {
  const double i = static_cast<double>((key >> 32) - kOffset);
  const double j = static_cast<double>((key & 0xffffffffLL) - kOffset);
  return Vec2((i + 0.5) * config_.cell_m, (j + 0.5) * config_.cell_m);
}

void ObstacleMemory::observe(const Vec2& position, double yaw, const RangeReading& reading) {
  if (reading.ranges.empty() || !(reading.hfov_rad > 0.0) || !(reading.range_m > 0.0)) {
    throw std::invalid_argument("ObstacleMemory: a reading needs rays, a field of view and a range");
  }
  const Vec2 camera = position + reading.camera_ahead_m * Vec2(std::cos(yaw), std::sin(yaw));
  const auto rays = static_cast<int>(reading.ranges.size());
  const double slice = reading.hfov_rad / rays;
  std::vector<std::int64_t> hits, cleared;
  for (int k = 0; k < rays; ++k) {
    const double bearing = yaw + 0.5 * reading.hfov_rad - (k + 0.5) * slice;
    const Vec2 d(std::cos(bearing), std::sin(bearing));
    const double r = std::clamp(static_cast<double>(reading.ranges[static_cast<std::size_t>(k)]),
                                0.0, 1.0) * reading.range_m;
    const bool hit = r < reading.range_m;
    if (hit) hits.push_back(key(camera + r * d));
    const double clear_to = hit ? r - config_.clear_margin_m : r;
    for (double s = 0.5 * config_.cell_m; s < clear_to; s += 0.5 * config_.cell_m) {
      cleared.push_back(key(camera + s * d));
    }
  }
  std::sort(hits.begin(), hits.end());
  std::sort(cleared.begin(), cleared.end());
  // Cleared cells go, unless this reading marks them too; then this reading's hits come in.
  std::vector<std::int64_t> kept;
  kept.reserve(cells_.size() + hits.size());
  for (const std::int64_t c : cells_) {
    if (!std::binary_search(cleared.begin(), cleared.end(), c) ||
        std::binary_search(hits.begin(), hits.end(), c)) {
      kept.push_back(c);
    }
  }
  kept.insert(kept.end(), hits.begin(), hits.end());
  std::sort(kept.begin(), kept.end());
  kept.erase(std::unique(kept.begin(), kept.end()), kept.end());
  const double far2 = config_.forget_beyond_m * config_.forget_beyond_m;
  std::erase_if(kept, [&](std::int64_t c) { return (centre(c) - position).squaredNorm() > far2; });
  cells_ = std::move(kept);
}

std::vector<KeepOut::Circle> ObstacleMemory::circles() const {
  std::vector<KeepOut::Circle> out;
  out.reserve(cells_.size());
  const double radius = config_.cell_m * std::sqrt(0.5);
  for (const std::int64_t c : cells_) out.push_back({centre(c), radius});
  return out;
}

}  // namespace syndds::convoy
