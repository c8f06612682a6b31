#include "scm/scm_terrain.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/thread_pool.hpp"

namespace syndds::scm {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// 4-neighbours in a fixed order (S, W, E, N): every traversal below is deterministic.
constexpr std::int32_t kNeighbourDi[4] = {0, -1, 1, 0};
constexpr std::int32_t kNeighbourDj[4] = {-1, 0, 0, 1};

bool finite(const Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

/// Total order over records of one vertex: true if (a, sa) beats (b, sb) (see docs/scm.md).
bool beats(const VertexChange& a, std::uint32_t sa, const VertexChange& b, std::uint32_t sb) {
  if (a.level_m != b.level_m) return a.level_m < b.level_m;
  if (a.sinkage_plastic_m != b.sinkage_plastic_m) return a.sinkage_plastic_m > b.sinkage_plastic_m;
  if (a.sigma_yield_pa != b.sigma_yield_pa) return a.sigma_yield_pa > b.sigma_yield_pa;
  if (a.level_initial_m != b.level_initial_m) return a.level_initial_m < b.level_initial_m;
  return sa < sb;
}

bool ij_less(const VertexChange& a, const VertexChange& b) {
  return a.i != b.i ? a.i < b.i : a.j < b.j;
}

/// Area and perimeter (in cell units) of the convex hull of the cells (unit squares centred
/// on the points). Andrew's monotone chain in exact integer arithmetic; `pts` gets sorted.
void hull_of_cells(std::vector<std::pair<std::int64_t, std::int64_t>>& pts, double& area,
                   double& perimeter) {
  std::sort(pts.begin(), pts.end());
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  const std::int64_t wx = pts.back().first - pts.front().first;
  std::int64_t ymin = pts.front().second, ymax = ymin;
  for (const auto& p : pts) {
    ymin = std::min(ymin, p.second);
    ymax = std::max(ymax, p.second);
  }
  const std::int64_t wy = ymax - ymin;
  std::vector<std::pair<std::int64_t, std::int64_t>> h;
  if (pts.size() >= 3) {
    auto cross = [](const auto& o, const auto& a, const auto& b) {
      return (a.first - o.first) * (b.second - o.second) -
             (a.second - o.second) * (b.first - o.first);
    };
    h.resize(2 * pts.size());
    std::size_t k = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      while (k >= 2 && cross(h[k - 2], h[k - 1], pts[i]) <= 0) --k;
      h[k++] = pts[i];
    }
    for (std::size_t i = pts.size() - 1, t = k + 1; i-- > 0;) {
      while (k >= t && cross(h[k - 2], h[k - 1], pts[i]) <= 0) --k;
      h[k++] = pts[i];
    }
    h.resize(k - 1);
  } else {
    h = pts;
  }
  std::int64_t twice_area = 0;
  double hull_perimeter = 0.0;
  const std::size_t n = h.size();
  if (n >= 3) {
    for (std::size_t i = 0; i < n; ++i) {
      const auto& a = h[i];
      const auto& b = h[(i + 1) % n];
      twice_area += a.first * b.second - b.first * a.second;
      hull_perimeter += std::hypot(static_cast<double>(b.first - a.first),
                                   static_cast<double>(b.second - a.second));
    }
  } else if (n == 2) {
    hull_perimeter = 2.0 * std::hypot(static_cast<double>(h[1].first - h[0].first),
                                      static_cast<double>(h[1].second - h[0].second));
  }
  // Minkowski sum with the unit cell: A + (width_x + width_y) + 1, P + 4.
  area = 0.5 * static_cast<double>(std::llabs(twice_area)) + static_cast<double>(wx + wy) + 1.0;
  perimeter = hull_perimeter + 4.0;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Per-step scratch

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
  std::int32_t record = -1;   // records_ index (contacts only)
  double z_hit = kInf;        // lowest body point on the vertical through the vertex
  std::int8_t face = 0;       // body face of that point (BodyGeometry::lowest_on_vertical)
  double surface = kInf;      // unloaded (plastic) surface, level_initial - sinkage_plastic,
  bool has_level = false;     // looked up only if z_hit < the level bound
};

struct BulldozeVertex {
  std::int32_t i = 0, j = 0;
  std::int32_t patch = -1;                       // last patch that listed it as rim
  std::int32_t neighbour[4] = {-1, -1, -1, -1};  // bd indices of the 4-neighbours in the domain
  double start = 0.0;                            // level when the erosion began
  double delta = 0.0;                            // material moved here by the erosion
};

struct ContactResult {
  Vec3 force = Vec3::Zero();
  Vec3 torque = Vec3::Zero();
  double sinkage = 0.0;
  bool loaded = false;
};

struct ScmTerrain::Scratch {
  std::vector<BodyGeometry> bodies;
  std::vector<StepVertex> vertices;          // all footprint vertices (see compute_body_loads)
  std::vector<std::int32_t> contacts;        // vertices indices of contact vertices
  std::vector<std::int32_t> contact_patch;   // patch id per contact
  std::vector<std::int32_t> patch_start;     // offsets into patch_members (size patches + 1)
  std::vector<std::int32_t> patch_members;   // contact indices grouped by patch
  std::vector<std::int32_t> patch_vertices;  // vertices indices of all patch vertices
  std::vector<double> patch_oob;             // 1 / b per patch
  std::vector<std::pair<std::int64_t, std::int64_t>> hull_points;
  std::vector<std::int32_t> row_min, row_max;
  std::vector<ContactResult> results;
  std::vector<ContactBody> wheel_bodies;
  // Bulldozing.
  std::vector<std::int32_t> cells;     // dense window: -2 not free, -1 free, >= 0 bd index
  std::vector<BulldozeVertex> bd;      // erosion domain: rims, then dilation rings
  std::vector<std::int32_t> boundary;  // bd indices of this patch's rim
};

// ---------------------------------------------------------------------------------------------

ScmTerrain::ScmTerrain(const ScmParams& params, std::shared_ptr<const terrain::TerrainSurface> base)
    : params_(params), base_(std::move(base)), scratch_(std::make_unique<Scratch>()) {
  validate(params_);
  delta_ = params_.grid.spacing_m;
  cell_area_ = delta_ * delta_;
  tan_phi_ = std::tan(deg_to_rad(params_.soil.friction_angle_deg));
  i_min_ = static_cast<std::int32_t>(std::ceil(params_.grid.x_min_m / delta_ - 1e-9));
  i_max_ = static_cast<std::int32_t>(std::floor(params_.grid.x_max_m / delta_ + 1e-9));
  j_min_ = static_cast<std::int32_t>(std::ceil(params_.grid.y_min_m / delta_ - 1e-9));
  j_max_ = static_cast<std::int32_t>(std::floor(params_.grid.y_max_m / delta_ + 1e-9));
  level_bound_ = base_ ? kInf : params_.grid.base_height_m;
  if (params_.threads > 1) pool_ = std::make_unique<ThreadPool>(params_.threads);
}

ScmTerrain::~ScmTerrain() = default;

double ScmTerrain::base_height(std::int32_t i, std::int32_t j) const {
  if (base_) return base_->height(i * delta_, j * delta_);
  return params_.grid.base_height_m;
}

double ScmTerrain::level_of(std::int32_t i, std::int32_t j) const {
  const std::int32_t r = find_record(i, j);
  return r >= 0 ? records_[static_cast<std::size_t>(r)].level : base_height(i, j);
}

double ScmTerrain::surface_of(std::int32_t i, std::int32_t j) const {
  const std::int32_t r = find_record(i, j);
  if (r < 0) return base_height(i, j);
  const Record& rec = records_[static_cast<std::size_t>(r)];
  return rec.level_initial - rec.sinkage_plastic;
}

double ScmTerrain::vertex_height(std::int32_t i, std::int32_t j) const { return level_of(i, j); }

std::optional<VertexChange> ScmTerrain::vertex(std::int32_t i, std::int32_t j) const {
  const std::int32_t r = find_record(i, j);
  if (r < 0) return std::nullopt;
  return to_change(records_[static_cast<std::size_t>(r)]);
}

double ScmTerrain::vertex_pressure(std::int32_t i, std::int32_t j) const {
  const std::int32_t r = find_record(i, j);
  if (r < 0) return 0.0;
  const Record& rec = records_[static_cast<std::size_t>(r)];
  return rec.contact_step == step_ - 1 ? rec.sigma : 0.0;
}

void ScmTerrain::note_level(double level) {
  if (level > level_bound_) level_bound_ = level;
}

std::int32_t ScmTerrain::get_or_insert_record(std::int32_t i, std::int32_t j) {
  const auto next = static_cast<std::int32_t>(records_.size());
  const std::int32_t r = index_.insert(vertex_key(i, j), next);
  if (r == next) {
    Record rec;
    rec.i = i;
    rec.j = j;
    rec.level = rec.level_initial = base_height(i, j);
    records_.push_back(rec);
    mark_dirty(r);  // a new record is new shared state: every copy must hold it
  }
  return r;
}

void ScmTerrain::mark_dirty(std::int32_t index) {
  Record& r = records_[static_cast<std::size_t>(index)];
  if (!r.dirty) {
    r.dirty = true;
    dirty_.push_back(index);
  }
}

VertexChange ScmTerrain::to_change(const Record& r) {
  VertexChange c;
  c.i = r.i;
  c.j = r.j;
  c.level_m = r.level;
  c.level_initial_m = r.level_initial;
  c.sinkage_plastic_m = r.sinkage_plastic;
  c.sigma_yield_pa = r.sigma_yield;
  return c;
}

void ScmTerrain::assign(Record& r, const VertexChange& c) {
  r.level = c.level_m;
  r.level_initial = c.level_initial_m;
  r.sinkage_plastic = c.sinkage_plastic_m;
  r.sigma_yield = c.sigma_yield_pa;
  note_level(r.level);
  note_level(r.level_initial - r.sinkage_plastic);
}

std::int32_t ScmTerrain::find_step_vertex(std::int32_t i, std::int32_t j) const {
  for (const BodyGeometry& g : scratch_->bodies) {
    if (g.count == 0 || i < g.i0 || i > g.i1 || j < g.j0 || j > g.j1) continue;
    return static_cast<std::int32_t>(
        g.offset + static_cast<std::size_t>(i - g.i0) * static_cast<std::size_t>(g.j1 - g.j0 + 1) +
        static_cast<std::size_t>(j - g.j0));
  }
  return -1;
}

// ---- TerrainSurface --------------------------------------------------------------------------

std::optional<ScmTerrain::Cell> ScmTerrain::cell_at(double x, double y) const {
  const double u = x / delta_;
  const double v = y / delta_;
  if (!(std::abs(u) < 2e9 && std::abs(v) < 2e9)) return std::nullopt;
  const double fu = std::floor(u);
  const double fv = std::floor(v);
  const auto i = static_cast<std::int32_t>(fu);
  const auto j = static_cast<std::int32_t>(fv);
  return Cell{u - fu,           v - fv,           level_of(i, j),
              level_of(i + 1, j), level_of(i, j + 1), level_of(i + 1, j + 1)};
}

double ScmTerrain::height(double x, double y) const {
  const auto c = cell_at(x, y);
  if (!c) return base_ ? base_->height(x, y) : params_.grid.base_height_m;
  return (1 - c->tv) * ((1 - c->tu) * c->h00 + c->tu * c->h10) +
         c->tv * ((1 - c->tu) * c->h01 + c->tu * c->h11);
}

Vec3 ScmTerrain::normal(double x, double y) const {
  const auto c = cell_at(x, y);
  if (!c) return base_ ? base_->normal(x, y) : Vec3::UnitZ();
  const double hx = ((1 - c->tv) * (c->h10 - c->h00) + c->tv * (c->h11 - c->h01)) / delta_;
  const double hy = ((1 - c->tu) * (c->h01 - c->h00) + c->tu * (c->h11 - c->h10)) / delta_;
  return Vec3(-hx, -hy, 1.0).normalized();
}

double ScmTerrain::friction(double, double) const { return tan_phi_; }

// ---- Contact -----------------------------------------------------------------------------------

void ScmTerrain::compute_wheel_loads(std::span<const terrain::WheelBodyState> wheels, double dt,
                                     std::span<terrain::WheelLoad> loads) {
  auto& bodies = scratch_->wheel_bodies;
  bodies.resize(wheels.size());
  for (std::size_t k = 0; k < wheels.size(); ++k) {
    bodies[k].pose = wheels[k].pose;
    bodies[k].linear_velocity = wheels[k].linear_velocity;
    bodies[k].angular_velocity = wheels[k].angular_velocity;
    bodies[k].shape = CylinderShape{wheels[k].radius_m, wheels[k].width_m};
  }
  compute_body_loads(bodies, dt, loads);
}

void ScmTerrain::compute_body_loads(std::span<const ContactBody> bodies, double dt,
                                    std::span<terrain::WheelLoad> loads) {
  if (bodies.size() != loads.size()) {
    throw std::invalid_argument("ScmTerrain::compute_body_loads: bodies and loads differ in size");
  }
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    throw std::invalid_argument("ScmTerrain::compute_body_loads: dt must be positive");
  }
  Scratch& s = *scratch_;
  stats_ = {};
  for (auto& l : loads) l = terrain::WheelLoad{};

  // ---- 1. Body geometry and footprints (grid boxes clipped to the area) ----
  s.bodies.assign(bodies.size(), BodyGeometry{});
  std::size_t total = 0;
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    const ContactBody& body = bodies[b];
    BodyGeometry& g = s.bodies[b];
    g.offset = total;
    if (!finite(body.pose.position) || !finite(body.linear_velocity) ||
        !finite(body.angular_velocity) || !std::isfinite(body.pose.orientation.norm())) {
      continue;  // no load for a body in an invalid state
    }
    const Eigen::Matrix3d rot = body.pose.orientation.normalized().toRotationMatrix();
    g.centre = body.pose.position;
    g.velocity = body.linear_velocity;
    g.omega = body.angular_velocity;
    Vec3 extent;
    if (const auto* cyl = std::get_if<CylinderShape>(&body.shape)) {
      if (!(cyl->radius_m > 0.0) || !(cyl->width_m > 0.0)) continue;
      g.cylinder = true;
      g.axis = rot.col(1);
      g.radius = cyl->radius_m;
      g.half_width = 0.5 * cyl->width_m;
      for (int k = 0; k < 3; ++k) {
        const double ak = g.axis[k];
        extent[k] =
            g.radius * std::sqrt(std::max(0.0, 1.0 - ak * ak)) + g.half_width * std::abs(ak);
      }
    } else {
      const auto& box = std::get<BoxShape>(body.shape);
      if (!(box.half_extents_m.array() > 0.0).all()) continue;
      g.cylinder = false;
      g.world_to_local = rot.transpose();
      g.half_extents = box.half_extents_m;
      extent = rot.cwiseAbs() * box.half_extents_m;
    }
    {  // secant slope of a circle of the body's size over its last grid cell (see the law)
      const double size = g.cylinder ? g.radius : g.half_extents.maxCoeff();
      g.slope_cap = std::sqrt(2.0 * size / delta_);
    }
    if (g.centre.z() - extent.z() >= level_bound_) continue;  // above all soil
    const double xl = (g.centre.x() - extent.x()) / delta_,
                 xh = (g.centre.x() + extent.x()) / delta_;
    const double yl = (g.centre.y() - extent.y()) / delta_,
                 yh = (g.centre.y() + extent.y()) / delta_;
    if (!(xh >= i_min_ && xl <= i_max_ && yh >= j_min_ && yl <= j_max_)) continue;
    g.i0 = std::max(
        i_min_, static_cast<std::int32_t>(std::ceil(std::max(xl, static_cast<double>(i_min_)))));
    g.i1 = std::min(
        i_max_, static_cast<std::int32_t>(std::floor(std::min(xh, static_cast<double>(i_max_)))));
    g.j0 = std::max(
        j_min_, static_cast<std::int32_t>(std::ceil(std::max(yl, static_cast<double>(j_min_)))));
    g.j1 = std::min(
        j_max_, static_cast<std::int32_t>(std::floor(std::min(yh, static_cast<double>(j_max_)))));
    if (g.i0 > g.i1 || g.j0 > g.j1) continue;
    g.count = static_cast<std::size_t>(g.i1 - g.i0 + 1) * static_cast<std::size_t>(g.j1 - g.j0 + 1);
    total += g.count;
  }
  stats_.footprint_vertices = total;

  // ---- 2. Ray casting: one vertical ray per footprint vertex (parallel, fixed partition) ----
  // Below a few thousand items per thread, waking the workers costs more than it saves, so the
  // work then runs on the calling thread. Results never depend on the number of parts.
  const auto grain = static_cast<std::size_t>(params_.thread_min_vertices);
  const bool parallel_cast = pool_ && total >= grain * static_cast<std::size_t>(pool_->size());
  const int parts = parallel_cast ? pool_->size() : 1;
  const double margin = params_.patch_test_height_m;
  if (total > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw std::invalid_argument("ScmTerrain::compute_body_loads: body footprints too large");
  }
  // One entry per footprint vertex, laid out body by body, row-major in each footprint box:
  // entry g is written by exactly one part, so the result does not depend on the partition.
  s.vertices.resize(total);
  auto cast = [&](int part) {
    const auto [g0, g1] = part_range(total, parts, part);
    for (std::size_t b = 0; b < s.bodies.size(); ++b) {
      const BodyGeometry& g = s.bodies[b];
      if (g.count == 0) continue;
      const std::size_t lo = std::max(g0, g.offset);
      const std::size_t hi = std::min(g1, g.offset + g.count);
      if (lo >= hi) continue;
      const std::size_t nj = static_cast<std::size_t>(g.j1 - g.j0 + 1);
      std::size_t local = lo - g.offset;
      auto i = static_cast<std::int32_t>(g.i0 + static_cast<std::int32_t>(local / nj));
      auto j = static_cast<std::int32_t>(g.j0 + static_cast<std::int32_t>(local % nj));
      for (std::size_t k = lo; k < hi; ++k) {
        StepVertex& v = s.vertices[k];
        v = StepVertex{};
        v.i = i;
        v.j = j;
        v.body = static_cast<std::int32_t>(b);
        double dz = 0.0;
        std::int8_t face = 0;
        if (g.lowest_on_vertical(i * delta_, j * delta_, dz, face)) {
          v.z_hit = g.centre.z() + dz;
          v.face = face;
          if (v.z_hit < level_bound_ + margin) {
            v.surface = surface_of(i, j);
            v.has_level = true;
          }
        }
        if (++j > g.j1) {
          j = g.j0;
          ++i;
        }
      }
    }
  };
  if (parallel_cast) {
    pool_->run(parts, cast);
  } else {
    cast(0);
  }

  // ---- 3. Vertices in several footprint boxes: the first box's entry is canonical and takes
  // the lowest body point (ties: the earlier body); the others become aliases ----
  bool overlap = false;
  for (std::size_t a = 0; a < s.bodies.size() && !overlap; ++a) {
    for (std::size_t b = a + 1; b < s.bodies.size() && !overlap; ++b) {
      const BodyGeometry& p = s.bodies[a];
      const BodyGeometry& q = s.bodies[b];
      overlap = p.count > 0 && q.count > 0 && p.i0 <= q.i1 && q.i0 <= p.i1 && p.j0 <= q.j1 &&
                q.j0 <= p.j1;
    }
  }
  if (overlap) {
    for (std::size_t k = 0; k < total; ++k) {
      StepVertex& h = s.vertices[k];
      const std::int32_t at = find_step_vertex(h.i, h.j);
      if (at == static_cast<std::int32_t>(k)) continue;
      h.alias = at;
      StepVertex& v = s.vertices[static_cast<std::size_t>(at)];
      if (h.has_level && !v.has_level) {
        v.surface = h.surface;
        v.has_level = true;
      }
      if (h.z_hit < v.z_hit) {
        v.z_hit = h.z_hit;
        v.face = h.face;
        v.body = h.body;
      }
    }
  }
  s.contacts.clear();
  std::size_t covered = 0;
  for (std::size_t k = 0; k < total; ++k) {
    StepVertex& v = s.vertices[k];
    if (v.alias >= 0 || v.z_hit == kInf) continue;
    ++covered;
    if (v.has_level && v.z_hit < v.surface) {  // elastic trial > 0
      v.contact = static_cast<std::int32_t>(s.contacts.size());
      s.contacts.push_back(static_cast<std::int32_t>(k));
    }
  }
  stats_.covered_vertices = covered;
  stats_.contact_vertices = s.contacts.size();
  if (s.contacts.empty()) {
    ++step_;
    return;
  }
  for (const std::int32_t k : s.contacts) {
    StepVertex& v = s.vertices[static_cast<std::size_t>(k)];
    v.record = get_or_insert_record(v.i, v.j);
  }

  // ---- 4. Contact patches: 4-connected sets of patch vertices (body less than the test height
  // above the unloaded soil) grown from the contacts; b = 2 A / P of the cells' convex hull ----
  const std::size_t nc = s.contacts.size();
  s.contact_patch.assign(nc, -1);
  s.patch_start.clear();
  s.patch_members.clear();
  s.patch_oob.clear();
  s.patch_vertices.clear();
  auto patch_vertex = [&](const StepVertex& v) {
    return v.has_level && v.z_hit < v.surface + margin;
  };
  for (std::size_t c0 = 0; c0 < nc; ++c0) {
    if (s.contact_patch[c0] >= 0) continue;
    const auto patch = static_cast<std::int32_t>(s.patch_start.size());
    s.patch_start.push_back(static_cast<std::int32_t>(s.patch_members.size()));
    const std::size_t first = s.patch_vertices.size();
    StepVertex& seed = s.vertices[static_cast<std::size_t>(s.contacts[c0])];
    seed.patch = patch;
    s.patch_vertices.push_back(s.contacts[c0]);
    for (std::size_t q = first; q < s.patch_vertices.size(); ++q) {  // breadth-first
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.patch_vertices[q])];
      if (v.contact >= 0) {
        s.contact_patch[static_cast<std::size_t>(v.contact)] = patch;
        s.patch_members.push_back(v.contact);
      }
      for (int n = 0; n < 4; ++n) {
        const std::int32_t at = find_step_vertex(v.i + kNeighbourDi[n], v.j + kNeighbourDj[n]);
        if (at < 0) continue;
        StepVertex& nb = s.vertices[static_cast<std::size_t>(at)];
        if (nb.patch >= 0 || !patch_vertex(nb)) continue;
        nb.patch = patch;
        s.patch_vertices.push_back(at);
      }
    }
    // Only the extreme vertices of each row can be on the convex hull.
    std::int32_t jlo = std::numeric_limits<std::int32_t>::max();
    std::int32_t jhi = std::numeric_limits<std::int32_t>::min();
    for (std::size_t q = first; q < s.patch_vertices.size(); ++q) {
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.patch_vertices[q])];
      jlo = std::min(jlo, v.j);
      jhi = std::max(jhi, v.j);
    }
    const auto rows = static_cast<std::size_t>(jhi - jlo + 1);
    s.row_min.assign(rows, std::numeric_limits<std::int32_t>::max());
    s.row_max.assign(rows, std::numeric_limits<std::int32_t>::min());
    for (std::size_t q = first; q < s.patch_vertices.size(); ++q) {
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.patch_vertices[q])];
      const auto row = static_cast<std::size_t>(v.j - jlo);
      s.row_min[row] = std::min(s.row_min[row], v.i);
      s.row_max[row] = std::max(s.row_max[row], v.i);
    }
    s.hull_points.clear();
    for (std::size_t row = 0; row < rows; ++row) {
      if (s.row_min[row] > s.row_max[row]) continue;
      const std::int64_t j = jlo + static_cast<std::int64_t>(row);
      s.hull_points.emplace_back(s.row_min[row], j);
      if (s.row_max[row] != s.row_min[row]) s.hull_points.emplace_back(s.row_max[row], j);
    }
    double area = 0.0, perimeter = 0.0;
    hull_of_cells(s.hull_points, area, perimeter);
    // 1/b = P / (2 A), with A in delta^2 and P in delta units.
    s.patch_oob.push_back(perimeter / (2.0 * area * delta_));
  }
  s.patch_start.push_back(static_cast<std::int32_t>(s.patch_members.size()));
  stats_.patches = s.patch_oob.size();
  stats_.patch_vertices = s.patch_vertices.size();

  // ---- 5. Per-vertex soil law (parallel over a fixed partition; each vertex is independent) ----
  s.results.assign(nc, ContactResult{});
  const SoilParams& soil = params_.soil;
  const double ke = soil.elastic_stiffness_pa_per_m;
  const double shear_damping_s = params_.shear_damping_time_s;
  const bool parallel_law = pool_ && 4 * nc >= grain * static_cast<std::size_t>(pool_->size());
  const int law_parts = parallel_law ? pool_->size() : 1;
  auto law = [&](int part) {
    const auto [c0, c1] = part_range(nc, law_parts, part);
    for (std::size_t c = c0; c < c1; ++c) {
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.contacts[c])];
      Record& r = records_[static_cast<std::size_t>(v.record)];
      ContactResult& out = s.results[c];
      const double sinkage = r.level_initial - v.z_hit;
      double sigma = ke * (sinkage - r.sinkage_plastic);  // elastic trial
      if (!(sigma > 0.0)) continue;                       // unilateral: no tension
      const BodyGeometry& g = s.bodies[static_cast<std::size_t>(v.body)];
      const Vec3 p(v.i * delta_, v.j * delta_, v.z_hit);
      const Vec3 arm = p - g.centre;
      const Vec3 vel = g.velocity + g.omega.cross(arm);
      const double vn = vel.z();
      // Shear mobilisation m = tau / tau_max (a horizontal vector, |m| <= 1) follows the slip
      // path of the body point over the soil: dm = (e - m) ds / K, e the slip direction and ds
      // the slip length (exact for a step of constant velocity). Monotonic slip j gives
      // |m| = 1 - exp(-j / K), Janosi-Hanamoto; at rest m keeps its value (a stiff spring of
      // tangent stiffness tau_max / K, no chatter) and a reversal unwinds it.
      double mx = 0.0, my = 0.0;
      if (r.contact_step == step_ - 1) {
        mx = r.shear_x;
        my = r.shear_y;
      }
      const double sx = vel.x() * dt, sy = vel.y() * dt;
      const double ds = std::hypot(sx, sy);
      double fmx = mx, fmy = my;  // mobilisation the force uses (see the shear damping below)
      if (ds > 0.0) {
        const double ex = sx / ds, ey = sy / ds;
        const double decay = std::exp(-ds / soil.janosi_shear_m);
        mx = ex + (mx - ex) * decay;
        my = ey + (my - ey) * decay;
        // Shear damping: the force takes the mobilisation reached after a further slip
        // |v_t| * beta, i.e. stiffness-proportional damping tau_max (e - m) |v_t| beta / K for
        // small slips, bounded by the Mohr-Coulomb strength (|m| <= 1).
        const double ahead = std::exp(-(ds / dt) * shear_damping_s / soil.janosi_shear_m);
        fmx = ex + (mx - ex) * ahead;
        fmy = ey + (my - ey) * ahead;
      }
      r.level = v.z_hit;
      r.step_plastic_flow = 0.0;
      if (sigma > r.sigma_yield) {  // plastic: follow the Bekker curve
        const double oob = s.patch_oob[static_cast<std::size_t>(s.contact_patch[c])];
        sigma = (soil.bekker_kc * oob + soil.bekker_kphi) * std::pow(sinkage, soil.bekker_n);
        r.sigma_yield = sigma;
        const double old_plastic = r.sinkage_plastic;
        r.sinkage_plastic = sinkage - sigma / ke;
        r.step_plastic_flow = r.sinkage_plastic - old_plastic;
      }
      // Damping (Chrono's, of the vertical motion): the total stress, clamped at zero, acts
      // vertically; of it, the soil stress (without the compressive damping) acts along the
      // body's outward surface normal n, as the radial stress of Bekker and Wong on a rigid
      // wheel. sigma is per unit horizontal area (the Bekker plate law), so that part adds the
      // horizontal sigma_n * (-n_h / |n_z|), the slope of the body surface over the vertex,
      // capped at the secant slope of the body's outline over its last grid cell (the cell is
      // not small against the body there).
      const double damped = sigma - vn * soil.damping_pa_s_per_m;
      const double sigma_n = std::max(0.0, std::min(sigma, damped));
      sigma = std::max(0.0, damped);
      double gx = 0.0, gy = 0.0;
      const Vec3 n = g.outward_normal(v.face, arm);
      if (n.z() < 0.0) {
        gx = n.x() / n.z();
        gy = n.y() / n.z();
        const double slope = std::hypot(gx, gy);
        if (slope > g.slope_cap) {
          gx *= g.slope_cap / slope;
          gy *= g.slope_cap / slope;
        }
      }
      const double tau_max = soil.cohesion_pa + sigma * tan_phi_;  // Mohr-Coulomb strength
      const Vec3 force(cell_area_ * (sigma_n * gx - tau_max * fmx),
                       cell_area_ * (sigma_n * gy - tau_max * fmy), cell_area_ * sigma);
      r.shear_x = mx;
      r.shear_y = my;
      r.sigma = sigma;
      r.contact_step = step_;
      out.force = force;
      out.torque = arm.cross(force);
      out.sinkage = sinkage;
      out.loaded = true;
    }
  };
  if (parallel_law) {
    pool_->run(law_parts, law);
  } else {
    law(0);
  }

  // ---- 6. Reduction in contact order (fixed, independent of the thread count) ----
  for (std::size_t c = 0; c < nc; ++c) {
    const ContactResult& out = s.results[c];
    if (!out.loaded) continue;
    const StepVertex& v = s.vertices[static_cast<std::size_t>(s.contacts[c])];
    mark_dirty(v.record);
    terrain::WheelLoad& l = loads[static_cast<std::size_t>(v.body)];
    l.force += out.force;
    l.torque += out.torque;
    l.sinkage_m = std::max(l.sinkage_m, out.sinkage);
    l.in_contact = true;
  }

  if (params_.bulldozing.enabled) bulldoze();
  ++step_;
}

// ---- Bulldozing --------------------------------------------------------------------------------
// (1) each patch's plastic flow of this step (times flow_factor) is spread evenly over its rim:
//     the 4-neighbours of loaded contact vertices that are inside the area, not in contact and
//     not under any body; (2) the rims are dilated `propagations` times over such vertices into
//     the erosion domain; (3) `iterations` sweeps move (|dh| - delta tan(angle)) / 4 from the
//     higher to the lower of each pair of 4-neighbours in the domain. Raising or moving material
//     shifts level and level_initial together, so the sinkage state is unchanged and the sum of
//     (level_initial - sinkage_plastic) is conserved for flow_factor = 1.
void ScmTerrain::bulldoze() {
  Scratch& s = *scratch_;
  const std::size_t patches = s.patch_oob.size();
  stats_.bulldozing_domain = 0;
  if (patches == 0) return;
  // All patches share one erosion domain (as in Chrono) when their common window is of
  // reasonable size; otherwise (bodies far apart) each patch is bulldozed in its own window.
  const std::int32_t margin = params_.bulldozing.propagations + 2;
  auto window_of = [&](std::size_t p0, std::size_t p1) {
    std::int32_t i0 = std::numeric_limits<std::int32_t>::max(), j0 = i0;
    std::int32_t i1 = std::numeric_limits<std::int32_t>::min(), j1 = i1;
    for (auto q = s.patch_start[p0]; q < s.patch_start[p1]; ++q) {
      const auto c = static_cast<std::size_t>(s.patch_members[static_cast<std::size_t>(q)]);
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.contacts[c])];
      i0 = std::min(i0, v.i);
      i1 = std::max(i1, v.i);
      j0 = std::min(j0, v.j);
      j1 = std::max(j1, v.j);
    }
    return std::array<std::int64_t, 4>{
        static_cast<std::int64_t>(i0) - margin, static_cast<std::int64_t>(i1) + margin,
        static_cast<std::int64_t>(j0) - margin, static_cast<std::int64_t>(j1) + margin};
  };
  const auto all = window_of(0, patches);
  const std::int64_t cells = (all[1] - all[0] + 1) * (all[3] - all[2] + 1);
  if (cells <= (std::int64_t{1} << 22)) {
    bulldoze_window(0, patches, all);
  } else {
    for (std::size_t p = 0; p < patches; ++p) bulldoze_window(p, p + 1, window_of(p, p + 1));
  }
}

void ScmTerrain::bulldoze_window(std::size_t p_begin, std::size_t p_end,
                                 const std::array<std::int64_t, 4>& window) {
  Scratch& s = *scratch_;
  const BulldozingParams& bp = params_.bulldozing;
  // Dense window over the patches (+ margin): cell = -2 not free (outside the area or under a
  // body), -1 free, >= 0 index into s.bd (the erosion domain).
  const std::int64_t wi0 = window[0], wj0 = window[2];
  const auto ww = static_cast<std::int32_t>(window[1] - window[0] + 1);
  const auto wh = static_cast<std::int32_t>(window[3] - window[2] + 1);
  s.cells.assign(static_cast<std::size_t>(ww) * static_cast<std::size_t>(wh), -2);
  auto cell_of = [&](std::int32_t i, std::int32_t j) {
    return static_cast<std::size_t>((j - wj0) * ww + (i - wi0));
  };
  {  // free inside the area
    const std::int64_t c0 = std::max<std::int64_t>(0, i_min_ - wi0);
    const std::int64_t c1 = std::min<std::int64_t>(ww - 1, i_max_ - wi0);
    const std::int64_t r0 = std::max<std::int64_t>(0, j_min_ - wj0);
    const std::int64_t r1 = std::min<std::int64_t>(wh - 1, j_max_ - wj0);
    for (std::int64_t r = r0; r <= r1; ++r) {
      auto row = s.cells.begin() + r * ww;
      std::fill(row + c0, row + c1 + 1, -1);
    }
  }
  for (const StepVertex& v : s.vertices) {  // covered vertices (contacts included)
    if (v.alias >= 0 || v.z_hit == kInf) continue;
    if (v.i >= wi0 && v.i < wi0 + ww && v.j >= wj0 && v.j < wj0 + wh)
      s.cells[cell_of(v.i, v.j)] = -2;
  }
  s.bd.clear();
  auto add_material = [&](std::int32_t i, std::int32_t j, double amount) {
    const std::int32_t r = get_or_insert_record(i, j);
    Record& rec = records_[static_cast<std::size_t>(r)];
    rec.level += amount;
    rec.level_initial += amount;
    note_level(rec.level);
    note_level(rec.level_initial - rec.sinkage_plastic);
    mark_dirty(r);
  };
  auto add_domain = [&](std::int32_t i, std::int32_t j, std::size_t cell) {
    const auto index = static_cast<std::int32_t>(s.bd.size());
    s.cells[cell] = index;
    BulldozeVertex v;
    v.i = i;
    v.j = j;
    s.bd.push_back(v);
    return index;
  };

  // (1) Raise the rim of each patch by its share of the patch's plastic flow.
  for (std::size_t p = p_begin; p < p_end; ++p) {
    double flow = 0.0;
    s.boundary.clear();
    for (auto q = s.patch_start[p]; q < s.patch_start[p + 1]; ++q) {
      const auto c = static_cast<std::size_t>(s.patch_members[static_cast<std::size_t>(q)]);
      if (!s.results[c].loaded) continue;
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.contacts[c])];
      flow += records_[static_cast<std::size_t>(v.record)].step_plastic_flow;
      for (int n = 0; n < 4; ++n) {
        const std::int32_t ni = v.i + kNeighbourDi[n], nj = v.j + kNeighbourDj[n];
        const std::size_t cell = cell_of(ni, nj);
        std::int32_t slot = s.cells[cell];
        if (slot == -2) continue;
        if (slot == -1) slot = add_domain(ni, nj, cell);
        auto& bv = s.bd[static_cast<std::size_t>(slot)];
        if (bv.patch == static_cast<std::int32_t>(p)) continue;
        bv.patch = static_cast<std::int32_t>(p);
        s.boundary.push_back(slot);
      }
    }
    if (s.boundary.empty()) continue;  // nowhere to put it: the volume is compacted instead
    const double raise = bp.flow_factor * flow / static_cast<double>(s.boundary.size());
    if (raise == 0.0) continue;
    for (const std::int32_t slot : s.boundary) {
      const auto& bv = s.bd[static_cast<std::size_t>(slot)];
      add_material(bv.i, bv.j, raise);
    }
  }
  const std::size_t rims = s.bd.size();
  if (rims == 0 || bp.iterations == 0) {
    stats_.bulldozing_domain += rims;
    return;
  }

  // (2) Erosion domain: the rims dilated `propagations` times over free vertices.
  std::size_t front_begin = 0, front_end = rims;
  for (int ring = 0; ring < bp.propagations && front_begin < front_end; ++ring) {
    for (std::size_t f = front_begin; f < front_end; ++f) {
      const std::int32_t i = s.bd[f].i, j = s.bd[f].j;
      for (int n = 0; n < 4; ++n) {
        const std::int32_t ni = i + kNeighbourDi[n], nj = j + kNeighbourDj[n];
        const std::size_t cell = cell_of(ni, nj);
        if (s.cells[cell] == -1) add_domain(ni, nj, cell);
      }
    }
    front_begin = front_end;
    front_end = s.bd.size();
  }
  stats_.bulldozing_domain += s.bd.size();
  for (auto& v : s.bd) {
    v.start = level_of(v.i, v.j);
    for (int n = 0; n < 4; ++n) {
      const std::int32_t c = s.cells[cell_of(v.i + kNeighbourDi[n], v.j + kNeighbourDj[n])];
      v.neighbour[n] = c >= 0 ? c : -1;
    }
  }

  // (3) Erosion sweeps (Gauss-Seidel in domain order) on cached heights, each pair of
  // 4-neighbours once per sweep (east and north links); stop early once a sweep moves nothing
  // (the remaining sweeps would not either).
  const double limit = delta_ * std::tan(deg_to_rad(bp.erosion_angle_deg));
  for (int iter = 0; iter < bp.iterations; ++iter) {
    bool moved = false;
    for (auto& v : s.bd) {
      for (int n = 2; n < 4; ++n) {  // kNeighbour order S, W, E, N
        if (v.neighbour[n] < 0) continue;
        auto& o = s.bd[static_cast<std::size_t>(v.neighbour[n])];
        const double dh = (v.start + v.delta) - (o.start + o.delta);
        const double excess = std::abs(dh) - limit;
        if (!(excess > 0.0)) continue;
        const double amount = excess / 4.0;
        if (dh > 0.0) {
          v.delta -= amount;
          o.delta += amount;
        } else {
          o.delta -= amount;
          v.delta += amount;
        }
        moved = true;
      }
    }
    if (!moved) break;
  }

  // (4) Write the moved material back (records only where something changed).
  for (const auto& v : s.bd) {
    if (v.delta != 0.0) add_material(v.i, v.j, v.delta);
  }
}

// ---- Sync ---------------------------------------------------------------------------------------

std::vector<VertexChange> ScmTerrain::take_local_changes() {
  claims_.clear();
  claim_source_.clear();
  std::vector<VertexChange> out;
  out.reserve(dirty_.size());
  for (const std::int32_t idx : dirty_) {
    Record& r = records_[static_cast<std::size_t>(idx)];
    r.dirty = false;
    out.push_back(to_change(r));
    claims_.insert(vertex_key(r.i, r.j), static_cast<std::int32_t>(claim_source_.size()));
    claim_source_.push_back(source_id_);
  }
  dirty_.clear();
  std::sort(out.begin(), out.end(), ij_less);
  return out;
}

void ScmTerrain::apply_remote_changes(std::uint32_t source_id,
                                      std::span<const VertexChange> changes) {
  for (const VertexChange& c : changes) {
    if (!in_area(c.i, c.j) || !std::isfinite(c.level_m) || !std::isfinite(c.level_initial_m) ||
        !std::isfinite(c.sinkage_plastic_m) || !std::isfinite(c.sigma_yield_pa)) {
      throw ProtocolError("SCM change from source " + std::to_string(source_id) + " at (" +
                          std::to_string(c.i) + ", " + std::to_string(c.j) +
                          ") is outside the area or not finite (terrain configs differ?)");
    }
  }
  for (const VertexChange& c : changes) {
    const std::uint64_t key = vertex_key(c.i, c.j);
    const auto next = static_cast<std::int32_t>(claim_source_.size());
    const std::int32_t claim = claims_.insert(key, next);
    const std::int32_t r = index_.insert(key, static_cast<std::int32_t>(records_.size()));
    if (r == static_cast<std::int32_t>(records_.size())) {
      Record rec;
      rec.i = c.i;
      rec.j = c.j;
      records_.push_back(rec);
    }
    Record& rec = records_[static_cast<std::size_t>(r)];
    if (claim == next) {  // first record of this frame for the vertex
      claim_source_.push_back(source_id);
      assign(rec, c);
      continue;
    }
    auto& holder = claim_source_[static_cast<std::size_t>(claim)];
    if (beats(c, source_id, to_change(rec), holder)) {
      assign(rec, c);
      holder = source_id;
    }
  }
}

ScmSnapshot ScmTerrain::snapshot() const {
  ScmSnapshot snap;
  snap.spacing_m = delta_;
  snap.vertices.reserve(records_.size());
  for (const Record& r : records_) snap.vertices.push_back(to_change(r));
  std::sort(snap.vertices.begin(), snap.vertices.end(), ij_less);
  return snap;
}

void ScmTerrain::load_snapshot(const ScmSnapshot& snap) {
  if (snap.spacing_m != delta_) {
    throw std::invalid_argument("ScmTerrain::load_snapshot: spacing " +
                                std::to_string(snap.spacing_m) + " differs from " +
                                std::to_string(delta_));
  }
  for (const VertexChange& c : snap.vertices) {
    if (!in_area(c.i, c.j)) {
      throw std::invalid_argument("ScmTerrain::load_snapshot: vertex outside the area");
    }
  }
  index_.clear();
  records_.clear();
  dirty_.clear();
  claims_.clear();
  claim_source_.clear();
  level_bound_ = base_ ? kInf : params_.grid.base_height_m;
  for (const VertexChange& c : snap.vertices) {
    const auto next = static_cast<std::int32_t>(records_.size());
    const std::int32_t r = index_.insert(vertex_key(c.i, c.j), next);
    if (r == next) {
      Record rec;
      rec.i = c.i;
      rec.j = c.j;
      records_.push_back(rec);
    }
    assign(records_[static_cast<std::size_t>(r)], c);
  }
}

std::uint64_t ScmTerrain::grid_hash() const {
  std::vector<VertexChange> all = snapshot().vertices;
  Fnv1a64 h;
  for (const VertexChange& c : all) {
    h.add_bytes(&c.i, sizeof c.i);
    h.add_bytes(&c.j, sizeof c.j);
    h.add(c.level_m);
    h.add(c.level_initial_m);
    h.add(c.sinkage_plastic_m);
    h.add(c.sigma_yield_pa);
  }
  return h.value();
}

double ScmTerrain::plastic_volume_change_m3() const {
  // Summed in (i, j) order so the result does not depend on insertion order.
  std::vector<VertexChange> all = snapshot().vertices;
  double sum = 0.0;
  for (const VertexChange& c : all) {
    sum += c.level_initial_m - c.sinkage_plastic_m - base_height(c.i, c.j);
  }
  return sum * cell_area_;
}

}  // namespace syndds::scm
