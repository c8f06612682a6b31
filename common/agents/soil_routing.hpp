#pragma once
// Soil routing (docs/scm.md, "Routing"): which soil records each vehicle receives. A routed
// vehicle subscribes to a box of tiles around its interest square (SoilSubscription) and tells
// the others with soil_interest samples; every writer addresses to each vehicle the records of
// its frame inside that vehicle's box (SoilBoxes); the recorder, which merges every list, sends
// a vehicle the tiles its box gains. Timing: a box published in frame p is used by the writers
// from frame p + 1 on and by the recorder in frame p + 1 (its state after the lists of frame p);
// the vehicle loads those tiles in frame p + 2, before it merges the lists of frame p + 1. So its
// interest square in frame k must lie in the box it published in frame k - 2 or earlier. Boxes
// published in frame 0 start on soil nobody has touched (nothing steps in frame 0).
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/state_io.hpp"
#include "protocol/messages.hpp"
#include "scm/scm_terrain.hpp"

namespace syndds::agents {

using TileBox = scm::Replication::IndexBox;

/// How far beyond its interest square a vehicle's box reaches (m): the box is renewed when the
/// square grown by the margin leaves it, to the square grown by twice the margin. A vehicle may
/// travel up to the margin in two frames.
inline constexpr double kRoutingMarginM = 2.0;

bool box_contains(const TileBox& outer, const TileBox& inner);
bool box_empty(const TileBox& b);
TileBox box_of(const proto::SoilInterestMsg& m);
/// The records of `list` (sorted) inside the tiles of `box`, in order: what a writer addresses
/// to the vehicle of that box.
std::vector<proto::TerrainVertexMsg> records_in(const std::vector<proto::TerrainVertexMsg>& list,
                                                const TileBox& box);

/// The boxes the routed vehicles subscribed to, from their soil_interest samples.
class SoilBoxes {
 public:
  struct Change {
    std::string vehicle_id;
    std::int64_t frame = 0;  // when it was published
    TileBox before;          // empty: the vehicle's first box
    TileBox now;
  };
  /// One frame's samples (at most one per vehicle); returns the changes in sample order.
  /// Samples of `self` are skipped.
  std::vector<Change> update(const std::vector<proto::SoilInterestMsg>& samples,
                             const std::string& self);
  const std::map<std::string, TileBox>& boxes() const { return boxes_; }
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  std::map<std::string, TileBox> boxes_;
};

/// A routed vehicle's own box and the changes it still has to load.
class SoilSubscription {
 public:
  explicit SoilSubscription(double radius_m) : radius_m_(radius_m) {}
  /// End of frame `frame`, chassis at (x, y): the new box if it has to change (publish it).
  std::optional<TileBox> renew(std::int64_t frame, const scm::ScmTerrain& soil, double x_m,
                               double y_m);
  /// Start of frame `frame`: the changes published in frame - 2 (to load now; never the first
  /// box); from now on the interest square must lie in the box as of then (check_covers).
  std::vector<SoilBoxes::Change> begin_frame(std::int64_t frame);
  /// Throws std::runtime_error naming the vehicle when `interest` (a vertex box) leaves the box
  /// the writers use in this frame (it moved farther than the margin in two frames).
  void check_covers(const std::string& vehicle_id, std::int64_t frame,
                    const TileBox& interest) const;
  const TileBox& box() const { return box_; }
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  double radius_m_;
  TileBox box_{0, -1, 0, -1};        // the newest published box
  TileBox effective_{0, -1, 0, -1};  // the box the writers use now
  bool has_effective_ = false;
  std::vector<SoilBoxes::Change> pending_;  // published, not yet in effect
};

}  // namespace syndds::agents
