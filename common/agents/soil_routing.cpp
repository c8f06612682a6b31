#include "agents/soil_routing.hpp"

#include <stdexcept>

#include <fmt/format.h>

namespace syndds::agents {
namespace {

void io_box(core::StateWriter& w, const TileBox& b) {
  w.io(b.i_lo);
  w.io(b.i_hi);
  w.io(b.j_lo);
  w.io(b.j_hi);
}
void io_box(core::StateReader& r, TileBox& b) {
  r.io(b.i_lo);
  r.io(b.i_hi);
  r.io(b.j_lo);
  r.io(b.j_hi);
}

}  // namespace

bool box_empty(const TileBox& b) { return b.i_hi < b.i_lo || b.j_hi < b.j_lo; }

bool box_contains(const TileBox& outer, const TileBox& inner) {
  return box_empty(inner) || (!box_empty(outer) && inner.i_lo >= outer.i_lo &&
                              inner.i_hi <= outer.i_hi && inner.j_lo >= outer.j_lo &&
                              inner.j_hi <= outer.j_hi);
}

TileBox box_of(const proto::SoilInterestMsg& m) {
  return {m.tile_i_lo, m.tile_i_hi, m.tile_j_lo, m.tile_j_hi};
}

std::vector<proto::TerrainVertexMsg> records_in(const std::vector<proto::TerrainVertexMsg>& list,
                                                const TileBox& box) {
  using scm::Replication;
  std::vector<proto::TerrainVertexMsg> out;
  for (const auto& v : list) {
    if (Replication::contains(box, v.i >> Replication::kTileShift, v.j >> Replication::kTileShift)) {
      out.push_back(v);
    }
  }
  return out;
}

std::vector<SoilBoxes::Change> SoilBoxes::update(
    const std::vector<proto::SoilInterestMsg>& samples, const std::string& self) {
  std::vector<Change> out;
  for (const auto& m : samples) {
    if (m.vehicle_id == self) continue;
    TileBox& box = boxes_[m.vehicle_id];
    Change c{m.vehicle_id, m.frame, box, box_of(m)};  // a new entry's box is empty
    box = c.now;
    out.push_back(std::move(c));
  }
  return out;
}

void SoilBoxes::save_state(core::StateWriter& w) const {
  w.io(static_cast<std::uint64_t>(boxes_.size()));
  for (const auto& [id, box] : boxes_) {
    w.io(id);
    io_box(w, box);
  }
}

void SoilBoxes::load_state(core::StateReader& r) {
  boxes_.clear();
  const auto n = r.get<std::uint64_t>();
  for (std::uint64_t k = 0; k < n; ++k) {
    auto id = r.get<std::string>();
    io_box(r, boxes_[id]);
  }
}

std::optional<TileBox> SoilSubscription::renew(std::int64_t frame, const scm::ScmTerrain& soil,
                                               double x_m, double y_m) {
  using scm::Replication;
  const TileBox need =
      Replication::tiles_of(soil.interest_box(x_m, y_m, radius_m_ + kRoutingMarginM));
  if (!box_empty(box_) && box_contains(box_, need)) return std::nullopt;
  const TileBox now =
      Replication::tiles_of(soil.interest_box(x_m, y_m, radius_m_ + 2.0 * kRoutingMarginM));
  pending_.push_back({"", frame, box_, now});
  box_ = now;
  return now;
}

std::vector<SoilBoxes::Change> SoilSubscription::begin_frame(std::int64_t frame) {
  std::vector<SoilBoxes::Change> due;
  std::size_t n = 0;
  while (n < pending_.size() && pending_[n].frame <= frame - 2) {
    effective_ = pending_[n].now;
    has_effective_ = true;
    if (pending_[n].frame > 0) due.push_back(pending_[n]);
    ++n;
  }
  pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n));
  return due;
}

void SoilSubscription::check_covers(const std::string& vehicle_id, std::int64_t frame,
                                    const TileBox& interest) const {
  if (!has_effective_) return;  // frames 0 and 1: nobody has touched the soil yet
  if (!box_contains(effective_, scm::Replication::tiles_of(interest))) {
    throw std::runtime_error(fmt::format(
        "vehicle {}: in frame {} its soil interest square left the box of tiles the others "
        "send it records of (soil routing allows {:g} m of travel in two frames; "
        "docs/scm.md, \"Routing\")",
        vehicle_id, frame, kRoutingMarginM));
  }
}

void SoilSubscription::save_state(core::StateWriter& w) const {
  io_box(w, box_);
  io_box(w, effective_);
  w.io(has_effective_);
  w.io(static_cast<std::uint64_t>(pending_.size()));
  for (const auto& c : pending_) {
    w.io(c.frame);
    io_box(w, c.before);
    io_box(w, c.now);
  }
}

void SoilSubscription::load_state(core::StateReader& r) {
  io_box(r, box_);
  io_box(r, effective_);
  r.io(has_effective_);
  pending_.assign(r.get<std::uint64_t>(), {});
  for (auto& c : pending_) {
    r.io(c.frame);
    io_box(r, c.before);
    io_box(r, c.now);
  }
}

}  // namespace syndds::agents
