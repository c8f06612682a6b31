#pragma once
// The geometric half of one SCM step, internal to syndds_scm: the bodies' shapes in the world,
// one entry per grid vertex under each body's footprint box (the vertical ray cast), the
// vertices in contact and their 4-connected contact patches with the Bekker 1 / b of each.
// ScmTerrain fills a ContactPatches step by step, the soil law adds the per-contact loads, and
// bulldozing reads the patches and loads to move the displaced soil.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "core/math.hpp"
#include "scm/soil_law.hpp"

namespace syndds::scm {

inline constexpr double kInf = std::numeric_limits<double>::infinity();
// 4-neighbours in a fixed order (S, W, E, N): every traversal is deterministic.
inline constexpr std::int32_t kNeighbourDi[4] = {0, -1, 1, 0};
inline constexpr std::int32_t kNeighbourDj[4] = {-1, 0, 0, 1};

struct BodyGeometry {
  bool cylinder = true;
  Vec3 centre = Vec3::Zero();
  Vec3 velocity = Vec3::Zero();
  Vec3 omega = Vec3::Zero();
  Vec3 axis = Vec3::UnitY();  // cylinder axis (world)
  double radius = 0.0;
  double half_width = 0.0;
  Eigen::Matrix3d world_to_local = Eigen::Matrix3d::Identity();  // box
  Vec3 half_extents = Vec3::Zero();
  double slope_cap = 0.0;  // largest horizontal/vertical ratio of the normal stress (see law)
  std::int32_t i0 = 0, i1 = -1, j0 = 0, j1 = -1;  // footprint (inclusive), clipped to area
  std::size_t count = 0;                          // footprint vertices
  std::size_t offset = 0;                         // first global footprint index

  /// Lowest point of the body on the vertical line through (x, y), relative to centre.z(), and
  /// the face it lies on (0: cylinder mantle; +-(k + 1): box face k or cylinder end cap (k = 1),
  /// sign of its outward normal along that local axis); false if the line misses the body.
  /// Inline: it runs once per footprint vertex.
  bool lowest_on_vertical(double x, double y, double& dz, std::int8_t& face) const {
    const double dx = x - centre.x();
    const double dy = y - centre.y();
    if (cylinder) {
      const double alpha = dx * axis.x() + dy * axis.y();
      const double az = axis.z();
      const double a = 1.0 - az * az;
      double t_lo = -kInf, t_hi = kInf;
      const double c = dx * dx + dy * dy - alpha * alpha - radius * radius;
      if (a < 1e-12) {  // vertical axis: a disc seen from below
        if (dx * dx + dy * dy > radius * radius) return false;
      } else {
        const double b = -2.0 * alpha * az;
        const double disc = b * b - 4.0 * a * c;
        if (disc < 0.0) return false;
        const double sq = std::sqrt(disc);
        t_lo = (-b - sq) / (2.0 * a);
        t_hi = (-b + sq) / (2.0 * a);
      }
      face = 0;
      if (std::abs(az) > 1e-12) {  // end caps: -h <= alpha + t az <= h
        double s0 = (-half_width - alpha) / az;
        double s1 = (half_width - alpha) / az;
        if (s0 > s1) std::swap(s0, s1);
        if (s0 > t_lo) {  // the ray enters through a cap: outward normal -sign(az) axis
          t_lo = s0;
          face = az > 0.0 ? -2 : 2;
        }
        t_hi = std::min(t_hi, s1);
      } else if (std::abs(alpha) > half_width) {
        return false;
      }
      if (t_lo > t_hi) return false;
      dz = t_lo;
      return true;
    }
    // Box: slab test of the line origin + t * e_z in the box frame.
    const Vec3 o = world_to_local * Vec3(dx, dy, 0.0);
    const Vec3 d = world_to_local.col(2);
    double t_lo = -kInf, t_hi = kInf;
    face = 0;
    for (int k = 0; k < 3; ++k) {
      if (std::abs(d[k]) < 1e-12) {
        if (std::abs(o[k]) > half_extents[k]) return false;
        continue;
      }
      double s0 = (-half_extents[k] - o[k]) / d[k];
      double s1 = (half_extents[k] - o[k]) / d[k];
      if (s0 > s1) std::swap(s0, s1);
      if (s0 > t_lo) {  // entry face so far: outward normal -sign(d[k]) e_k
        t_lo = s0;
        face = static_cast<std::int8_t>(d[k] > 0.0 ? -(k + 1) : k + 1);
      }
      t_hi = std::min(t_hi, s1);
    }
    if (t_lo > t_hi) return false;
    dz = t_lo;
    return true;
  }

  /// Outward unit normal of the body at a surface point (arm = point - centre) on `face`.
  Vec3 outward_normal(std::int8_t face, const Vec3& arm) const {
    if (cylinder) {
      if (face != 0) return face > 0 ? axis : Vec3(-axis);
      const Vec3 radial = arm - arm.dot(axis) * axis;
      const double len = radial.norm();
      return len > 0.0 ? Vec3(radial / len) : Vec3(-Vec3::UnitZ());
    }
    if (face == 0) return -Vec3::UnitZ();
    const int k = std::abs(face) - 1;
    const Vec3 e = world_to_local.row(k).transpose();  // local axis k in the world
    return face > 0 ? e : Vec3(-e);
  }
};

struct StepVertex {  // one footprint vertex of one body in this step
  std::int32_t i = 0, j = 0;
  std::int32_t body = -1;
  std::int32_t alias = -1;    // canonical entry if an earlier body's footprint holds the vertex
  std::int32_t contact = -1;  // index in contacts, -1 if not penetrating
  std::int32_t patch = -1;    // contact patch (patch vertices reached from a contact only)
  std::int32_t record = -1;   // VertexGrid record index (contacts only)
  double z_hit = kInf;        // lowest body point on the vertical through the vertex
  std::int8_t face = 0;       // body face of that point (BodyGeometry::lowest_on_vertical)
  double surface = kInf;      // unloaded (plastic) surface, level_initial - sinkage_plastic,
  bool has_level = false;     // looked up only if z_hit < the level bound
};

/// Everything one step finds out about the contact, kept between steps to avoid allocations.
struct ContactPatches {
  std::vector<BodyGeometry> bodies;
  std::vector<StepVertex> vertices;          // all footprint vertices, body by body, row-major
  std::vector<std::int32_t> contacts;        // vertices indices of contact vertices
  std::vector<std::int32_t> contact_patch;   // patch id per contact
  std::vector<std::int32_t> patch_start;     // offsets into patch_members (size patches + 1)
  std::vector<std::int32_t> patch_members;   // contact indices grouped by patch
  std::vector<std::int32_t> patch_vertices;  // vertices indices of all patch vertices
  std::vector<double> patch_oob;             // 1 / b per patch
  std::vector<VertexLoad> loads;             // per contact, from the soil law
  // Work arrays of find_patches.
  std::vector<std::pair<std::int64_t, std::int64_t>> hull_points;
  std::vector<std::int32_t> row_min, row_max;

  std::size_t patches() const { return patch_oob.size(); }

  /// Footprint entry of vertex (i, j) in this step (the first body box holding it), or -1.
  std::int32_t find_vertex(std::int32_t i, std::int32_t j) const {
    for (const BodyGeometry& g : bodies) {
      if (g.count == 0 || i < g.i0 || i > g.i1 || j < g.j0 || j > g.j1) continue;
      return static_cast<std::int32_t>(g.offset +
                                       static_cast<std::size_t>(i - g.i0) *
                                           static_cast<std::size_t>(g.j1 - g.j0 + 1) +
                                       static_cast<std::size_t>(j - g.j0));
    }
    return -1;
  }
};

/// Area and perimeter (in cell units) of the convex hull of the cells (unit squares centred
/// on the points). Andrew's monotone chain in exact integer arithmetic; `pts` gets sorted.
void hull_of_cells(std::vector<std::pair<std::int64_t, std::int64_t>>& pts, double& area,
                   double& perimeter);

/// Groups the contacts into 4-connected patches of patch vertices (the body less than
/// `test_height` above the unloaded soil), grown breadth-first from the contacts in order,
/// and sets each patch's 1 / b = P / (2 A) from the convex hull of its cells (spacing `delta`).
void find_patches(ContactPatches& s, double test_height, double delta);

}  // namespace syndds::scm
