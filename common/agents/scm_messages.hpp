#pragma once
// SCM vertex records <-> wire messages (header-only: the recorder uses it too).
#include <vector>

#include "protocol/messages.hpp"
#include "scm/scm_terrain.hpp"

namespace syndds::agents {

inline proto::TerrainVertexMsg to_message(const scm::VertexChange& v) {
  return {v.i, v.j, v.level_m, v.level_initial_m, v.sinkage_plastic_m, v.sigma_yield_pa};
}

inline scm::VertexChange from_message(const proto::TerrainVertexMsg& v) {
  return {v.i, v.j, v.height, v.level_initial, v.sinkage_plastic, v.sigma_yield};
}

inline std::vector<scm::VertexChange> from_messages(const std::vector<proto::TerrainVertexMsg>& in) {
  std::vector<scm::VertexChange> out;
  out.reserve(in.size());
  for (const auto& v : in) out.push_back(from_message(v));
  return out;
}

}  // namespace syndds::agents
