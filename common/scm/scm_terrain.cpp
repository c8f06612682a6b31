#include "scm/scm_terrain.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/state_io.hpp"
#include "core/thread_pool.hpp"
#include "scm/bulldozing.hpp"
#include "scm/contact_patch.hpp"

namespace syndds::scm {
namespace {

bool finite(const Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

/// Throws ConfigError before any member is built from invalid parameters.
const ScmParams& validated(const ScmParams& params) {
  validate(params);
  return params;
}

/// What a checkpoint must match: the grid geometry and every parameter that changes a result.
/// Not here: threads and thread_min_vertices (results do not depend on them) and
/// interest_radius_m (the agent's choice of box; merges end the same either way). A base
/// surface is represented by its height at the grid's corners and centre.
std::vector<std::pair<std::string, double>> fingerprint(const ScmParams& p, const VertexGrid& g) {
  const SoilParams& s = p.soil;
  const BulldozingParams& b = p.bulldozing;
  std::vector<std::pair<std::string, double>> f = {
      {"grid spacing_m", p.grid.spacing_m},
      {"grid x_min_m", p.grid.x_min_m},
      {"grid x_max_m", p.grid.x_max_m},
      {"grid y_min_m", p.grid.y_min_m},
      {"grid y_max_m", p.grid.y_max_m},
      {"grid base_height_m", p.grid.base_height_m},
      {"soil bekker_kphi", s.bekker_kphi},
      {"soil bekker_kc", s.bekker_kc},
      {"soil bekker_n", s.bekker_n},
      {"soil cohesion_pa", s.cohesion_pa},
      {"soil friction_angle_deg", s.friction_angle_deg},
      {"soil janosi_shear_m", s.janosi_shear_m},
      {"soil elastic_stiffness_pa_per_m", s.elastic_stiffness_pa_per_m},
      {"soil damping_pa_s_per_m", s.damping_pa_s_per_m},
      {"bulldozing enabled", b.enabled ? 1.0 : 0.0},
      {"bulldozing erosion_angle_deg", b.erosion_angle_deg},
      {"bulldozing flow_factor", b.flow_factor},
      {"bulldozing iterations", static_cast<double>(b.iterations)},
      {"bulldozing propagations", static_cast<double>(b.propagations)},
      {"patch_test_height_m", p.patch_test_height_m},
      {"shear_damping_time_s", p.shear_damping_time_s},
      {"base surface", g.base() ? 1.0 : 0.0},
  };
  if (g.base()) {
    const std::int32_t is[3] = {g.i_min(), g.i_min() + (g.i_max() - g.i_min()) / 2, g.i_max()};
    const std::int32_t js[3] = {g.j_min(), g.j_min() + (g.j_max() - g.j_min()) / 2, g.j_max()};
    for (const std::int32_t i : is) {
      for (const std::int32_t j : js) {
        f.emplace_back("base surface height at vertex (" + std::to_string(i) + ", " +
                           std::to_string(j) + ")",
                       g.base_height(i, j));
      }
    }
  }
  return f;
}

// Shortest text that reads back as the same double ("0.05", not "0.050000000000000003").
std::string shortest(double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, res.ptr);
}

}  // namespace

/// The per-step working state, kept between calls to avoid allocations.
struct ScmTerrain::StepData {
  explicit StepData(const BulldozingParams& bulldozing) : bulldozer(bulldozing) {}
  ContactPatches patches;
  Bulldozer bulldozer;
  std::vector<ContactBody> wheel_bodies;
};

ScmTerrain::ScmTerrain(const ScmParams& params, std::shared_ptr<const terrain::TerrainSurface> base)
    : params_(validated(params)),
      grid_(params_.grid, std::move(base)),
      law_(params_.soil, params_.shear_damping_time_s,
           params_.grid.spacing_m * params_.grid.spacing_m),
      step_data_(std::make_unique<StepData>(params_.bulldozing)) {
  if (params_.threads > 1) pool_ = std::make_unique<ThreadPool>(params_.threads);
}

ScmTerrain::~ScmTerrain() = default;

std::optional<VertexChange> ScmTerrain::vertex(std::int32_t i, std::int32_t j) const {
  const std::int32_t r = grid_.find(i, j);
  if (r < 0) return std::nullopt;
  return to_change(grid_.record(r));
}

double ScmTerrain::vertex_pressure(std::int32_t i, std::int32_t j) const {
  const std::int32_t r = grid_.find(i, j);
  if (r < 0) return 0.0;
  const VertexRecord& rec = grid_.record(r);
  return rec.contact_step == step_ - 1 ? rec.sigma : 0.0;
}

// ---- TerrainSurface --------------------------------------------------------------------------

std::optional<ScmTerrain::Cell> ScmTerrain::cell_at(double x, double y) const {
  const double u = x / grid_.spacing();
  const double v = y / grid_.spacing();
  if (!(std::abs(u) < 2e9 && std::abs(v) < 2e9)) return std::nullopt;
  const double fu = std::floor(u);
  const double fv = std::floor(v);
  const auto i = static_cast<std::int32_t>(fu);
  const auto j = static_cast<std::int32_t>(fv);
  return Cell{u - fu,
              v - fv,
              grid_.level_of(i, j),
              grid_.level_of(i + 1, j),
              grid_.level_of(i, j + 1),
              grid_.level_of(i + 1, j + 1)};
}

double ScmTerrain::height(double x, double y) const {
  const auto c = cell_at(x, y);
  if (!c) return grid_.base() ? grid_.base()->height(x, y) : grid_.base_height_m();
  return (1 - c->tv) * ((1 - c->tu) * c->h00 + c->tu * c->h10) +
         c->tv * ((1 - c->tu) * c->h01 + c->tu * c->h11);
}

Vec3 ScmTerrain::normal(double x, double y) const {
  const auto c = cell_at(x, y);
  if (!c) return grid_.base() ? grid_.base()->normal(x, y) : Vec3::UnitZ();
  const double hx = ((1 - c->tv) * (c->h10 - c->h00) + c->tv * (c->h11 - c->h01)) / grid_.spacing();
  const double hy = ((1 - c->tu) * (c->h01 - c->h00) + c->tu * (c->h11 - c->h10)) / grid_.spacing();
  return Vec3(-hx, -hy, 1.0).normalized();
}

double ScmTerrain::friction(double, double) const { return law_.tan_phi(); }

// ---- Contact -----------------------------------------------------------------------------------

void ScmTerrain::compute_wheel_loads(std::span<const terrain::WheelBodyState> wheels, double dt,
                                     std::span<terrain::WheelLoad> loads) {
  auto& bodies = step_data_->wheel_bodies;
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
  stats_ = {};
  for (auto& l : loads) l = terrain::WheelLoad{};
  ContactPatches& s = step_data_->patches;

  // Find the contact patches: footprints, one vertical ray per footprint vertex, the vertices
  // below the unloaded soil, their 4-connected patches.
  const std::size_t total = place_bodies(bodies);
  stats_.footprint_vertices = total;
  cast_rays(total);
  collect_contacts(total);
  stats_.contact_vertices = s.contacts.size();
  if (s.contacts.empty()) {
    ++step_;
    return;
  }
  for (const std::int32_t k : s.contacts) {
    StepVertex& v = s.vertices[static_cast<std::size_t>(k)];
    v.record = grid_.get_or_insert(v.i, v.j);
  }
  find_patches(s, params_.patch_test_height_m, grid_.spacing());
  stats_.patches = s.patches();
  stats_.patch_vertices = s.patch_vertices.size();

  // Per-vertex Bekker / Janosi stress, then the forces summed per body.
  apply_soil_law(dt);
  integrate_loads(loads);

  if (params_.bulldozing.enabled) {
    stats_.bulldozing_domain = step_data_->bulldozer.run(grid_, s);
  }
  ++step_;
}

// Body geometry and footprints (grid boxes clipped to the area); returns the number of
// footprint vertices.
std::size_t ScmTerrain::place_bodies(std::span<const ContactBody> bodies) {
  ContactPatches& s = step_data_->patches;
  const double delta = grid_.spacing();
  const double level_bound = grid_.level_bound();
  const std::int32_t i_min = grid_.i_min(), i_max = grid_.i_max();
  const std::int32_t j_min = grid_.j_min(), j_max = grid_.j_max();
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
      g.slope_cap = std::sqrt(2.0 * size / delta);
    }
    // Above all soil, with the patch test's margin: what follows then never depends on the
    // bound's value as long as it covers the soil under the bodies (see cast_rays), so soil far
    // away that this process has not merged yet cannot change a load here.
    if (g.centre.z() - extent.z() >= level_bound + params_.patch_test_height_m) continue;
    const double xl = (g.centre.x() - extent.x()) / delta, xh = (g.centre.x() + extent.x()) / delta;
    const double yl = (g.centre.y() - extent.y()) / delta, yh = (g.centre.y() + extent.y()) / delta;
    if (!(xh >= i_min && xl <= i_max && yh >= j_min && yl <= j_max)) continue;
    g.i0 = std::max(i_min,
                    static_cast<std::int32_t>(std::ceil(std::max(xl, static_cast<double>(i_min)))));
    g.i1 = std::min(
        i_max, static_cast<std::int32_t>(std::floor(std::min(xh, static_cast<double>(i_max)))));
    g.j0 = std::max(j_min,
                    static_cast<std::int32_t>(std::ceil(std::max(yl, static_cast<double>(j_min)))));
    g.j1 = std::min(
        j_max, static_cast<std::int32_t>(std::floor(std::min(yh, static_cast<double>(j_max)))));
    if (g.i0 > g.i1 || g.j0 > g.j1) continue;
    g.count = static_cast<std::size_t>(g.i1 - g.i0 + 1) * static_cast<std::size_t>(g.j1 - g.j0 + 1);
    total += g.count;
  }
  return total;
}

// One vertical ray per footprint vertex (parallel over a fixed partition). Below a few thousand
// items per thread, waking the workers costs more than it saves, so the work then runs on the
// calling thread. Results never depend on the number of parts.
void ScmTerrain::cast_rays(std::size_t total) {
  ContactPatches& s = step_data_->patches;
  const double delta = grid_.spacing();
  const double level_bound = grid_.level_bound();
  const double test_height = params_.patch_test_height_m;
  const auto grain = static_cast<std::size_t>(params_.thread_min_vertices);
  const bool parallel_cast = pool_ && total >= grain * static_cast<std::size_t>(pool_->size());
  const int parts = parallel_cast ? pool_->size() : 1;
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
        if (g.lowest_on_vertical(i * delta, j * delta, dz, face)) {
          v.z_hit = g.centre.z() + dz;
          v.face = face;
          // Without a level the vertex is neither a contact nor a patch vertex, as it would not
          // be with one: z_hit >= bound + test_height >= its surface + test_height.
          if (v.z_hit < level_bound + test_height) {
            v.surface = grid_.surface_of(i, j);
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
}

// Vertices in several footprint boxes: the first box's entry is canonical and takes the lowest
// body point (ties: the earlier body); the others become aliases. Then the contacts: covered
// vertices below the unloaded soil, in footprint order.
void ScmTerrain::collect_contacts(std::size_t total) {
  ContactPatches& s = step_data_->patches;
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
      const std::int32_t at = s.find_vertex(h.i, h.j);
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
}

// The soil law at each contact (parallel over a fixed partition; each vertex is independent).
void ScmTerrain::apply_soil_law(double dt) {
  ContactPatches& s = step_data_->patches;
  const std::size_t nc = s.contacts.size();
  s.loads.assign(nc, VertexLoad{});
  const double delta = grid_.spacing();
  const auto grain = static_cast<std::size_t>(params_.thread_min_vertices);
  const bool parallel_law = pool_ && 4 * nc >= grain * static_cast<std::size_t>(pool_->size());
  const int law_parts = parallel_law ? pool_->size() : 1;
  auto law = [&](int part) {
    const auto [c0, c1] = part_range(nc, law_parts, part);
    for (std::size_t c = c0; c < c1; ++c) {
      const StepVertex& v = s.vertices[static_cast<std::size_t>(s.contacts[c])];
      const BodyGeometry& g = s.bodies[static_cast<std::size_t>(v.body)];
      ContactPoint point;
      point.z_hit = v.z_hit;
      point.arm = Vec3(v.i * delta, v.j * delta, v.z_hit) - g.centre;
      point.velocity = g.velocity + g.omega.cross(point.arm);
      point.normal = g.outward_normal(v.face, point.arm);
      point.slope_cap = g.slope_cap;
      const double oob = s.patch_oob[static_cast<std::size_t>(s.contact_patch[c])];
      s.loads[c] = law_.apply(grid_.record(v.record), point, oob, step_, dt);
    }
  };
  if (parallel_law) {
    pool_->run(law_parts, law);
  } else {
    law(0);
  }
}

// The loads summed per body in contact order (fixed, independent of the thread count).
void ScmTerrain::integrate_loads(std::span<terrain::WheelLoad> loads) {
  const ContactPatches& s = step_data_->patches;
  const std::size_t nc = s.contacts.size();
  for (std::size_t c = 0; c < nc; ++c) {
    const VertexLoad& out = s.loads[c];
    if (!out.loaded) continue;
    const StepVertex& v = s.vertices[static_cast<std::size_t>(s.contacts[c])];
    grid_.mark_dirty(v.record);
    terrain::WheelLoad& l = loads[static_cast<std::size_t>(v.body)];
    l.force += out.force;
    l.torque += out.torque;
    l.sinkage_m = std::max(l.sinkage_m, out.sinkage);
    l.in_contact = true;
  }
}

// ---- Sync ---------------------------------------------------------------------------------------

std::vector<VertexChange> ScmTerrain::take_local_changes() {
  return replication_.take_local_changes(grid_);
}

void ScmTerrain::apply_remote_changes(std::uint32_t source_id,
                                      std::span<const VertexChange> changes) {
  replication_.apply_remote_changes(grid_, source_id, changes);
}

Replication::IndexBox ScmTerrain::interest_box(double x_m, double y_m, double radius_m) const {
  const double d = grid_.spacing();
  Replication::IndexBox box;
  box.i_lo = static_cast<std::int32_t>(std::floor((x_m - radius_m) / d));
  box.i_hi = static_cast<std::int32_t>(std::ceil((x_m + radius_m) / d));
  box.j_lo = static_cast<std::int32_t>(std::floor((y_m - radius_m) / d));
  box.j_hi = static_cast<std::int32_t>(std::ceil((y_m + radius_m) / d));
  return box;
}

void ScmTerrain::set_interest_region(double x_m, double y_m, double radius_m) {
  replication_.set_interest(grid_, interest_box(x_m, y_m, radius_m));
}

namespace {
void require_merged(const Replication& r, const char* what) {
  if (r.deferred_tiles() > 0) {
    throw std::logic_error(std::string("ScmTerrain::") + what +
                           ": deformations are deferred (interest management); flush_deferred() "
                           "first");
  }
}
}  // namespace

std::vector<VertexChange> ScmTerrain::added_tiles_state(const Replication::IndexBox& now,
                                                        const Replication::IndexBox& before) const {
  require_merged(replication_, "added_tiles_state");
  return Replication::added_tiles_state(grid_, now, before);
}

ScmSnapshot ScmTerrain::snapshot() const {
  require_merged(replication_, "snapshot");
  return Replication::snapshot(grid_);
}

void ScmTerrain::load_snapshot(const ScmSnapshot& snap) { replication_.load_snapshot(grid_, snap); }

std::uint64_t ScmTerrain::grid_hash() const {
  require_merged(replication_, "grid_hash");
  return Replication::grid_hash(grid_);
}

// ---- Checkpoints --------------------------------------------------------------------------------

// Member by member: params_ and law_ are construction data (checked through the fingerprint);
// grid_ and replication_ write their own sections; step_ is kept (the contact state is relative
// to it) and so is stats_ (last_step_stats() is read after a frame). Not kept: step_data_
// (per-step work arrays and the bulldozer's, rebuilt by every step before they are read) and
// pool_ (results do not depend on the thread count).
void ScmTerrain::save_state(core::StateWriter& w) const {
  w.begin("scm_terrain", 1);
  const auto f = fingerprint(params_, grid_);
  w.io(static_cast<std::uint32_t>(f.size()));
  for (const auto& [name, value] : f) w.io(value);
  w.io(step_);
  for (const std::size_t v : {stats_.footprint_vertices, stats_.covered_vertices,
                              stats_.contact_vertices, stats_.patches, stats_.patch_vertices,
                              stats_.bulldozing_domain}) {
    w.io(static_cast<std::uint64_t>(v));
  }
  grid_.save_state(w, step_ - 1);
  replication_.save_state(w);
  w.end();
}

void ScmTerrain::load_state(core::StateReader& r) {
  r.begin("scm_terrain", 1);
  const auto f = fingerprint(params_, grid_);
  const auto n = r.get<std::uint32_t>();
  if (n != f.size()) {
    r.fail("the state is of another kind of soil (" + std::to_string(n) +
           " fingerprint values, this terrain has " + std::to_string(f.size()) +
           "; a base surface on one side only?)");
  }
  for (const auto& [name, value] : f) {
    const auto saved = r.get<double>();
    if (std::bit_cast<std::uint64_t>(saved) != std::bit_cast<std::uint64_t>(value)) {
      r.fail("the state is of another grid or soil: " + name + " is " + shortest(saved) +
             " in the state and " + shortest(value) + " in this terrain");
    }
  }
  r.io(step_);
  for (std::size_t* v : {&stats_.footprint_vertices, &stats_.covered_vertices,
                         &stats_.contact_vertices, &stats_.patches, &stats_.patch_vertices,
                         &stats_.bulldozing_domain}) {
    *v = static_cast<std::size_t>(r.get<std::uint64_t>());
  }
  grid_.load_state(r, step_ - 1);
  replication_.load_state(r, grid_);
  r.end();
}

double ScmTerrain::plastic_volume_change_m3() const {
  // Summed in (i, j) order so the result does not depend on insertion order.
  std::vector<VertexChange> all = snapshot().vertices;
  double sum = 0.0;
  for (const VertexChange& c : all) {
    sum += c.level_initial_m - c.sinkage_plastic_m - grid_.base_height(c.i, c.j);
  }
  return sum * grid_.cell_area();
}

}  // namespace syndds::scm
