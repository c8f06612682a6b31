#pragma once
// SCM bulldozing, internal to syndds_scm: moves the soil that a step's contact patches pressed
// down plastically to the rims of the patches and erodes the rims to the angle of repose.
//   (1) each patch's plastic flow of this step (times flow_factor) is spread evenly over its rim:
//       the 4-neighbours of loaded contact vertices that are inside the area, not in contact and
//       not under any body; (2) the rims are dilated `propagations` times over such vertices into
//       the erosion domain; (3) `iterations` sweeps move (|dh| - delta tan(angle)) / 4 from the
//       higher to the lower of each pair of 4-neighbours in the domain. Raising or moving
//       material shifts level and level_initial together, so the sinkage state is unchanged and
//       the sum of (level_initial - sinkage_plastic) is conserved for flow_factor = 1.
#include <array>
#include <cstdint>
#include <vector>

#include "scm/contact_patch.hpp"
#include "scm/scm_params.hpp"
#include "scm/vertex_grid.hpp"

namespace syndds::scm {

class Bulldozer {
 public:
  explicit Bulldozer(const BulldozingParams& params) : params_(params) {}

  /// Bulldozes the patches of one step (after the soil law has filled `s.loads`); returns the
  /// number of vertices in the erosion domain.
  std::size_t run(VertexGrid& grid, const ContactPatches& s);

 private:
  struct DomainVertex {
    std::int32_t i = 0, j = 0;
    std::int32_t patch = -1;                       // last patch that listed it as rim
    std::int32_t neighbour[4] = {-1, -1, -1, -1};  // bd_ indices of the 4-neighbours in the domain
    double start = 0.0;                            // level when the erosion began
    double delta = 0.0;                            // material moved here by the erosion
  };

  std::size_t run_window(VertexGrid& grid, const ContactPatches& s, std::size_t p_begin,
                         std::size_t p_end, const std::array<std::int64_t, 4>& window);

  BulldozingParams params_;
  // Work arrays, kept between steps to avoid allocations.
  std::vector<std::int32_t> cells_;     // dense window: -2 not free, -1 free, >= 0 bd_ index
  std::vector<DomainVertex> bd_;        // erosion domain: rims, then dilation rings
  std::vector<std::int32_t> boundary_;  // bd_ indices of this patch's rim
};

}  // namespace syndds::scm
