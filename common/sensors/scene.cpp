#include "sensors/scene.hpp"

#include "core/error.hpp"
#include "core/hash.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

namespace syndds::sensors {
namespace {

// Drops hits on the vehicle a sensor rides on (see HidingContext).
void hide_vehicle_filter(const RTCFilterFunctionNArguments* args) {
  const auto* ctx = reinterpret_cast<const HidingContext*>(args->context);
  const int slot = static_cast<int>(reinterpret_cast<std::intptr_t>(args->geometryUserPtr));
  if (ctx->hidden_slot != slot) return;
  for (unsigned i = 0; i < args->N; ++i) args->valid[i] = 0;
}

// Closed cylinder around the local axis `axis` (1: y for wheels, 2: z for obstacles):
// two rings of `segments` vertices, then the two cap centres.
std::vector<Vec3> cylinder_vertices(double radius, double half_length, int axis, int segments) {
  std::vector<Vec3> v;
  v.reserve(2 * static_cast<std::size_t>(segments) + 2);
  for (int side = 0; side < 2; ++side) {
    const double h = side == 0 ? -half_length : half_length;
    for (int s = 0; s < segments; ++s) {
      const double a = 2.0 * std::numbers::pi * s / segments;
      const double c = radius * std::cos(a), d = radius * std::sin(a);
      v.push_back(axis == 1 ? Vec3(c, h, d) : Vec3(c, d, h));
    }
  }
  v.push_back(axis == 1 ? Vec3(0, -half_length, 0) : Vec3(0, 0, -half_length));
  v.push_back(axis == 1 ? Vec3(0, half_length, 0) : Vec3(0, 0, half_length));
  return v;
}

void cylinder_triangles(unsigned base, int segments, std::vector<std::array<unsigned, 3>>& out) {
  const auto n = static_cast<unsigned>(segments);
  const unsigned c0 = base + 2 * n, c1 = c0 + 1;
  for (unsigned s = 0; s < n; ++s) {
    const unsigned a0 = base + s, a1 = base + (s + 1) % n;
    const unsigned b0 = base + n + s, b1 = base + n + (s + 1) % n;
    out.push_back({a0, a1, b1});
    out.push_back({a0, b1, b0});
    out.push_back({c0, a1, a0});
    out.push_back({c1, b0, b1});
  }
}

std::vector<Vec3> box_vertices(const Vec3& half) {
  std::vector<Vec3> v;
  for (int k = 0; k < 8; ++k) {
    v.emplace_back((k & 1) ? half.x() : -half.x(), (k & 2) ? half.y() : -half.y(),
                   (k & 4) ? half.z() : -half.z());
  }
  return v;
}

void box_triangles(unsigned base, std::vector<std::array<unsigned, 3>>& out) {
  static constexpr unsigned faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces) {
    out.push_back({base + f[0], base + f[1], base + f[2]});
    out.push_back({base + f[0], base + f[2], base + f[3]});
  }
}

// A wheel around its local y axis: tread rings (radius r) at -w/2 and +w/2, hub rings (radius
// kHubRadiusShare r) at -w/2 and +w/2, then the two hub centres.
std::vector<Vec3> wheel_vertices(double radius, double half_width, int segments) {
  std::vector<Vec3> v;
  v.reserve(4 * static_cast<std::size_t>(segments) + 2);
  for (const double r : {radius, kHubRadiusShare * radius}) {
    for (const double h : {-half_width, half_width}) {
      for (int s = 0; s < segments; ++s) {
        const double a = 2.0 * std::numbers::pi * s / segments;
        v.emplace_back(r * std::cos(a), h, r * std::sin(a));
      }
    }
  }
  v.emplace_back(0.0, -half_width, 0.0);
  v.emplace_back(0.0, half_width, 0.0);
  return v;
}

// Tread, two sidewalls (tyre) and two hub discs whose sectors alternate hub / tyre colour.
void wheel_triangles(unsigned base, int segments, std::vector<std::array<unsigned, 3>>& out,
                     std::vector<std::uint8_t>& parts) {
  const auto n = static_cast<unsigned>(segments);
  const auto tyre = static_cast<std::uint8_t>(VehiclePart::tyre);
  const auto hub = static_cast<std::uint8_t>(VehiclePart::hub);
  const unsigned m0 = base + 4 * n, m1 = m0 + 1;
  for (unsigned s = 0; s < n; ++s) {
    const unsigned t = (s + 1) % n;
    const unsigned a0 = base + s, a1 = base + t;                  // tread, -w/2
    const unsigned b0 = base + n + s, b1 = base + n + t;          // tread, +w/2
    const unsigned h0 = base + 2 * n + s, h1 = base + 2 * n + t;  // hub, -w/2
    const unsigned g0 = base + 3 * n + s, g1 = base + 3 * n + t;  // hub, +w/2
    const std::uint8_t sector =
        (static_cast<int>(s) * kHubSectors / segments) % 2 == 0 ? hub : tyre;
    for (const auto& tri : {std::array<unsigned, 3>{a0, a1, b1}, {a0, b1, b0},  // tread
                            {a0, h0, h1}, {a0, h1, a1}, {b0, b1, g1}, {b0, g1, g0}}) {
      out.push_back(tri);
      parts.push_back(tyre);
    }
    out.push_back({m0, h1, h0});
    parts.push_back(sector);
    out.push_back({m1, g0, g1});
    parts.push_back(sector);
  }
}

// New triangle mesh with `vertex_count` float3 vertices and the given triangles.
RTCGeometry make_mesh(RTCDevice device, std::size_t vertex_count,
                      const std::vector<std::array<unsigned, 3>>& triangles, float** vertices) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  *vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
      g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertex_count));
  auto* index = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles.size()));
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) index[3 * t + k] = triangles[t][k];
  }
  return g;
}

void store(float* dst, std::size_t index, const Vec3& p) {
  dst[3 * index + 0] = static_cast<float>(p.x());
  dst[3 * index + 1] = static_cast<float>(p.y());
  dst[3 * index + 2] = static_cast<float>(p.z());
}

float srgb_to_linear(float v) { return std::pow(v, 2.2f); }

}  // namespace

TerrainGrid TerrainGrid::flat(const Vec2& origin, double spacing_m, int nx, int ny,
                              double height_m) {
  TerrainGrid g;
  g.origin = origin;
  g.spacing_m = spacing_m;
  g.nx = nx;
  g.ny = ny;
  g.heights.assign(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny),
                   static_cast<float>(height_m));
  return g;
}

TerrainGrid sample_terrain(const terrain::TerrainSurface& surface, double spacing_m, double x_min,
                           double x_max, double y_min, double y_max) {
  if (!(spacing_m > 0.0) || !(x_max > x_min) || !(y_max > y_min)) {
    throw std::invalid_argument("sample_terrain: need spacing > 0 and a non-empty area");
  }
  const auto i0 = static_cast<int>(std::ceil(x_min / spacing_m - 1e-9));
  const auto i1 = static_cast<int>(std::floor(x_max / spacing_m + 1e-9));
  const auto j0 = static_cast<int>(std::ceil(y_min / spacing_m - 1e-9));
  const auto j1 = static_cast<int>(std::floor(y_max / spacing_m + 1e-9));
  TerrainGrid g = TerrainGrid::flat(Vec2(i0 * spacing_m, j0 * spacing_m), spacing_m, i1 - i0 + 1,
                                    j1 - j0 + 1, 0.0);
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      g.at(i, j) = static_cast<float>(surface.height((i0 + i) * spacing_m, (j0 + j) * spacing_m));
    }
  }
  return g;
}

TerrainLook terrain_look(std::string_view kind) {
  TerrainLook look;
  if (kind == "rigid") {
    look.colour = {0.5f, 0.5f, 0.5f};
    look.reflectance = 0.3f;
  } else if (kind == "silt" || kind == "scm" || kind == "soil") {
    look.colour = {0.45f, 0.30f, 0.16f};
    look.reflectance = 0.25f;
  } else if (kind == "snow") {
    look.colour = {0.92f, 0.93f, 0.95f};
    look.reflectance = 0.8f;
  } else {
    throw std::invalid_argument("unknown terrain look '" + std::string(kind) +
                                "' (rigid | silt | snow)");
  }
  return look;
}

VehicleShape vehicle_shape(const vehicle::VehicleParams& p, const Rgb& body_colour) {
  VehicleShape s;
  s.half_extents_m = p.chassis.half_extents_m;
  s.box_centre_m = p.chassis.box_centre_m;
  s.wheel_radius_m = p.wheels.radius_m;
  s.wheel_width_m = p.wheels.width_m;
  s.wheel_positions_m = {
      Vec3(p.front.x_m, p.front.half_track_m, 0.0), Vec3(p.front.x_m, -p.front.half_track_m, 0.0),
      Vec3(p.rear.x_m, p.rear.half_track_m, 0.0), Vec3(p.rear.x_m, -p.rear.half_track_m, 0.0)};
  s.body_colour = body_colour;
  return s;
}

std::array<DrawnBox, 3> vehicle_body_boxes(const VehicleShape& shape) {
  const Vec3& c = shape.box_centre_m;
  const Vec3& h = shape.half_extents_m;
  const double bottom = c.z() - h.z(), top = c.z() + h.z();
  double axle = 0.0, inner = std::numeric_limits<double>::infinity();
  for (const auto& w : shape.wheel_positions_m) {
    axle += 0.25 * w.z();
    inner = std::min(inner, std::abs(w.y() - c.y()) - 0.5 * shape.wheel_width_m - 0.03);
  }
  auto box = [](double x0, double x1, double y0, double y1, double z0, double z1) {
    return DrawnBox{Vec3(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * (z0 + z1)),
                    Vec3(0.5 * (x1 - x0), 0.5 * (y1 - y0), 0.5 * (z1 - z0))};
  };
  const double height = top - bottom;
  // Deck from 3 cm above the tyres (kept within the chassis box), 30 % of what is left above.
  const double deck0 = std::clamp(axle + shape.wheel_radius_m + 0.03, bottom + 0.2 * height,
                                  top - 0.3 * height);
  const double deck1 = deck0 + std::max(0.08, 0.3 * (top - deck0));
  const double hull_y = std::clamp(inner, 0.2 * h.y(), h.y());
  const double hull0 = std::clamp(axle, bottom, deck0 - 0.05 * height);
  return {box(c.x() - h.x(), c.x() + h.x(), c.y() - hull_y, c.y() + hull_y, hull0, deck0),
          box(c.x() - h.x(), c.x() + h.x(), c.y() - h.y(), c.y() + h.y(), deck0, deck1),
          box(c.x() - 0.55 * h.x(), c.x() + 0.25 * h.x(), c.y() - 0.9 * h.y(),
              c.y() + 0.9 * h.y(), deck1, top)};
}

Rgb vehicle_palette(std::size_t index) {
  static constexpr Rgb palette[] = {
      {0.10f, 0.25f, 0.80f}, {0.80f, 0.10f, 0.10f}, {0.90f, 0.75f, 0.05f}, {0.10f, 0.65f, 0.20f},
      {0.60f, 0.15f, 0.70f}, {0.05f, 0.70f, 0.75f}, {0.95f, 0.45f, 0.05f}, {0.85f, 0.85f, 0.85f}};
  return palette[index % std::size(palette)];
}

Rgb obstacle_colour(std::string_view label) {
  if (label == "rock") return {0.42f, 0.38f, 0.34f};
  if (label == "tree") return {0.12f, 0.40f, 0.10f};
  if (label == "bush") return {0.20f, 0.50f, 0.15f};
  if (label == "wall") return {0.70f, 0.70f, 0.72f};
  return {0.95f, 0.40f, 0.05f};
}

Vec3 SceneConfig::sun_direction() const {
  const double az = deg_to_rad(sun_azimuth_deg), el = deg_to_rad(sun_elevation_deg);
  return Vec3(std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el));
}

Scene::Scene(const SceneConfig& config) : config_(config) {
  if (config.terrain_tile_cells < 1) throw std::invalid_argument("terrain_tile_cells must be >= 1");
  if (config.cylinder_segments < 3) throw std::invalid_argument("cylinder_segments must be >= 3");
  const std::string device_config =
      config.embree_threads > 0 ? "threads=" + std::to_string(config.embree_threads) : "";
  device_ = rtcNewDevice(device_config.empty() ? nullptr : device_config.c_str());
  if (!device_) throw std::runtime_error("Embree: cannot create device");
  scene_ = rtcNewScene(device_);
  // ROBUST: watertight ray-quad tests, so rays cannot slip through the seams of the terrain
  // mesh (without it a camera looking straight down sees a few sky pixels).
  rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_LOW);
  check_device("scene creation");
}

Scene::~Scene() {
  for (auto& [id, v] : vehicles_) rtcReleaseGeometry(v.geometry);
  rtcReleaseScene(scene_);
  rtcReleaseDevice(device_);
}

void Scene::check_device(const char* what) const {
  const RTCError e = rtcGetDeviceError(device_);
  if (e != RTC_ERROR_NONE) {
    throw std::runtime_error(std::string("Embree error ") + std::to_string(static_cast<int>(e)) +
                             " during " + what);
  }
}

const TriMesh* Scene::mesh(const std::string& name) {
  if (config_.mesh_dir.empty() || name.empty()) return nullptr;
  auto it = meshes_.find(name);
  if (it == meshes_.end()) {
    const auto file = std::filesystem::path(config_.mesh_dir) / (name + ".obj");
    const bool present = std::filesystem::is_regular_file(file);
    if (const auto expected = config_.mesh_hashes.find(name); expected != config_.mesh_hashes.end()) {
      // The bytes drawn are the bytes fingerprinted: every process of the run agreed on them.
      std::uint64_t hash = 0;
      if (present) {
        std::ifstream in(file, std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        hash = fnv1a64(bytes);
      }
      if (hash != expected->second) {
        throw ConfigError("mesh " + file.string() + " " +
                          (present ? "changed" : "disappeared") +
                          " after the scenario was loaded (the run's fingerprint has " +
                          (expected->second ? "hash " + hex64(expected->second) : "it absent") +
                          ", now " + (present ? "hash " + hex64(hash) : "absent") + ")");
      }
    }
    std::optional<TriMesh> m;
    if (present) m = load_mesh(file.string());
    it = meshes_.emplace(name, std::move(m)).first;
  }
  return it->second ? &*it->second : nullptr;
}

unsigned Scene::attach(RTCGeometry geometry, const Surface& surface) {
  rtcCommitGeometry(geometry);
  const unsigned id = rtcAttachGeometry(scene_, geometry);
  rtcReleaseGeometry(geometry);  // the scene holds it now
  if (surfaces_.size() <= id) surfaces_.resize(id + 1);
  surfaces_[id] = surface;
  dirty_ = true;
  return id;
}

void Scene::detach(unsigned id) {
  rtcDetachGeometry(scene_, id);
  dirty_ = true;
}

namespace {
// Drawn vertices along one side of a tile of `cells` cells drawn every `step` vertices.
int drawn_count(int cells, int step) { return (cells + step - 1) / step + 1; }
std::size_t drawn_quads(int cells_x, int cells_y, int step) {
  return static_cast<std::size_t>(drawn_count(cells_x, step) - 1) *
         static_cast<std::size_t>(drawn_count(cells_y, step) - 1);
}
}  // namespace

void Scene::clear_terrain() {
  for (auto& t : tiles_) {
    primitive_count_ -= drawn_quads(t.cells_x, t.cells_y, t.step);
    detach(t.id);
  }
  tiles_.clear();
}

void Scene::set_terrain(const TerrainGrid& grid, const TerrainLook& look, int coarse_stride) {
  if (grid.nx < 2 || grid.ny < 2 || !(grid.spacing_m > 0.0) ||
      grid.heights.size() !=
          static_cast<std::size_t>(grid.nx) * static_cast<std::size_t>(grid.ny)) {
    throw std::invalid_argument("terrain grid: need nx, ny >= 2, spacing > 0 and nx*ny heights");
  }
  if (coarse_stride < 1) throw std::invalid_argument("terrain coarse stride must be >= 1");
  std::vector<float> texture;
  int tw = 0, th = 0;
  if (!look.texture_file.empty()) {
    const cv::Mat img = cv::imread(look.texture_file, cv::IMREAD_COLOR);
    if (img.empty())
      throw std::invalid_argument("cannot read terrain texture " + look.texture_file);
    if (!(look.texture_size_m > 0.0)) throw std::invalid_argument("texture_size_m must be > 0");
    tw = img.cols;
    th = img.rows;
    texture.resize(static_cast<std::size_t>(tw) * th * 3);
    for (int y = 0; y < th; ++y) {
      for (int x = 0; x < tw; ++x) {
        const auto& bgr = img.at<cv::Vec3b>(y, x);
        // Image row 0 is the top (north edge) of one repeat.
        const std::size_t o = (static_cast<std::size_t>(th - 1 - y) * tw + x) * 3;
        texture[o + 0] = srgb_to_linear(bgr[2] / 255.0f);
        texture[o + 1] = srgb_to_linear(bgr[1] / 255.0f);
        texture[o + 2] = srgb_to_linear(bgr[0] / 255.0f);
      }
    }
  }
  clear_terrain();
  grid_ = grid;
  look_ = look;
  texture_ = std::move(texture);
  texture_width_ = tw;
  texture_height_ = th;
  coarse_stride_ = coarse_stride;

  const int cells_x = grid.nx - 1, cells_y = grid.ny - 1;
  const int t = config_.terrain_tile_cells;
  tiles_x_ = (cells_x + t - 1) / t;
  tiles_y_ = (cells_y + t - 1) / t;
  Surface surface;
  surface.kind = SurfaceKind::terrain;
  surface.colour = look.colour;
  surface.reflectance = look.reflectance;
  tiles_.resize(static_cast<std::size_t>(tiles_x_) * tiles_y_);
  for (int ty = 0; ty < tiles_y_; ++ty) {
    for (int tx = 0; tx < tiles_x_; ++tx) {
      Tile& tile = tiles_[static_cast<std::size_t>(ty) * tiles_x_ + tx];
      tile.tx = tx;
      tile.ty = ty;
      tile.i0 = tx * t;
      tile.j0 = ty * t;
      tile.cells_x = std::min(t, cells_x - tile.i0);
      tile.cells_y = std::min(t, cells_y - tile.j0);
      tile.step = coarse_stride;
      tile.geometry = make_tile_geometry(tile, false);
      tile.id = attach(tile.geometry, surface);
      primitive_count_ += drawn_quads(tile.cells_x, tile.cells_y, tile.step);
    }
  }
  check_device("terrain creation");
}

std::size_t Scene::fine_terrain_tiles() const {
  return static_cast<std::size_t>(
      std::count_if(tiles_.begin(), tiles_.end(), [](const Tile& t) { return t.step == 1; }));
}

Scene::Tile* Scene::tile_at(int tx, int ty) {
  if (tx < 0 || ty < 0 || tx >= tiles_x_ || ty >= tiles_y_) return nullptr;
  return &tiles_[static_cast<std::size_t>(ty) * tiles_x_ + tx];
}

// A quad mesh of the tile's drawn vertices at its step; `flat`: every height 0 (the layout the
// BVH of a refined tile is built over, see commit()).
RTCGeometry Scene::make_tile_geometry(Tile& tile, bool flat) {
  const int vx = drawn_count(tile.cells_x, tile.step), vy = drawn_count(tile.cells_y, tile.step);
  RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_QUAD);
  tile.vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
      g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
      static_cast<std::size_t>(vx) * static_cast<std::size_t>(vy)));
  auto* index = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT4, 4 * sizeof(unsigned),
                              static_cast<std::size_t>(vx - 1) * static_cast<std::size_t>(vy - 1)));
  for (int lj = 0; lj < vy; ++lj) {
    const int j = tile.j0 + std::min(lj * tile.step, tile.cells_y);
    for (int li = 0; li < vx; ++li) {
      const int i = tile.i0 + std::min(li * tile.step, tile.cells_x);
      const std::size_t v = static_cast<std::size_t>(lj) * vx + li;
      tile.vertices[3 * v + 0] = static_cast<float>(grid_.origin.x() + i * grid_.spacing_m);
      tile.vertices[3 * v + 1] = static_cast<float>(grid_.origin.y() + j * grid_.spacing_m);
      tile.vertices[3 * v + 2] = flat ? 0.0f : drawn_height(tile, i, j);
    }
  }
  std::size_t q = 0;
  for (int lj = 0; lj + 1 < vy; ++lj) {
    for (int li = 0; li + 1 < vx; ++li, ++q) {
      const auto v00 = static_cast<unsigned>(lj * vx + li);
      index[4 * q + 0] = v00;
      index[4 * q + 1] = v00 + 1;
      index[4 * q + 2] = v00 + 1 + static_cast<unsigned>(vx);
      index[4 * q + 3] = v00 + static_cast<unsigned>(vx);
    }
  }
  rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_REFIT);
  return g;
}

// Height drawn at grid vertex (i, j) of a fine tile: the grid's, except on a side shared with
// a coarse neighbour, where it lies on that neighbour's straight edge between its drawn
// vertices (a T-junction without a crack). Such a vertex never changed: a change to it would
// have refined the neighbour too.
float Scene::drawn_height(const Tile& tile, int i, int j) const {
  if (tile.step == 1 && coarse_stride_ > 1) {
    const int s = coarse_stride_;
    auto coarse = [&](int tx, int ty) {
      if (tx < 0 || ty < 0 || tx >= tiles_x_ || ty >= tiles_y_) return false;
      return tiles_[static_cast<std::size_t>(ty) * tiles_x_ + tx].step != 1;
    };
    // Along a side: offset `l` of `cells` from the side's start, drawn every s.
    auto on_edge = [&](int l, int cells, auto&& at) -> std::optional<float> {
      const int a = (l / s) * s, b = std::min(a + s, cells);
      if (a == l) return std::nullopt;  // a drawn vertex of the neighbour: the grid's height
      const double w = static_cast<double>(l - a) / (b - a);
      return static_cast<float>((1.0 - w) * at(a) + w * at(b));
    };
    const bool west = i == tile.i0 && coarse(tile.tx - 1, tile.ty);
    const bool east = i == tile.i0 + tile.cells_x && coarse(tile.tx + 1, tile.ty);
    if (west || east) {
      if (auto z = on_edge(j - tile.j0, tile.cells_y,
                           [&](int l) { return static_cast<double>(grid_.at(i, tile.j0 + l)); })) {
        return *z;
      }
    }
    const bool south = j == tile.j0 && coarse(tile.tx, tile.ty - 1);
    const bool north = j == tile.j0 + tile.cells_y && coarse(tile.tx, tile.ty + 1);
    if (south || north) {
      if (auto z = on_edge(i - tile.i0, tile.cells_x,
                           [&](int l) { return static_cast<double>(grid_.at(tile.i0 + l, j)); })) {
        return *z;
      }
    }
  }
  return grid_.at(i, j);
}

void Scene::write_tile_vertex(Tile& tile, int i, int j) {
  const int li = i - tile.i0, lj = j - tile.j0;  // a fine tile: drawn vertex = grid vertex
  const std::size_t v = static_cast<std::size_t>(lj) * (tile.cells_x + 1) + li;
  tile.vertices[3 * v + 2] = drawn_height(tile, i, j);
}

// Redraws a coarse tile at the grid's spacing. The new mesh keeps the tile's geometry id (so
// the scene is the same whatever order tiles were refined in) and is built flat: commit()
// builds its BVH over that layout and then refits it to the heights, so that the BVH depends
// only on the tile's extent, never on the moment it was refined (a run resumed from a
// checkpoint draws the same frames as one that never stopped).
void Scene::refine_tile(Tile& tile) {
  primitive_count_ -= drawn_quads(tile.cells_x, tile.cells_y, tile.step);
  rtcDetachGeometry(scene_, tile.id);
  tile.step = 1;
  tile.fresh = true;
  tile.dirty = false;
  tile.geometry = make_tile_geometry(tile, true);
  rtcCommitGeometry(tile.geometry);
  rtcAttachGeometryByID(scene_, tile.geometry, tile.id);
  rtcReleaseGeometry(tile.geometry);  // the scene holds it
  primitive_count_ += drawn_quads(tile.cells_x, tile.cells_y, 1);
  dirty_ = true;
  // Fine neighbours drew their side facing this tile on its coarse edge: now the grid's.
  const int dx[4] = {-1, 1, 0, 0}, dy[4] = {0, 0, -1, 1};
  for (int k = 0; k < 4; ++k) {
    Tile* n = tile_at(tile.tx + dx[k], tile.ty + dy[k]);
    if (!n || n->step != 1 || n->fresh) continue;
    if (dx[k] != 0) {
      const int i = dx[k] < 0 ? n->i0 + n->cells_x : n->i0;
      for (int j = n->j0; j <= n->j0 + n->cells_y; ++j) write_tile_vertex(*n, i, j);
    } else {
      const int j = dy[k] < 0 ? n->j0 + n->cells_y : n->j0;
      for (int i = n->i0; i <= n->i0 + n->cells_x; ++i) write_tile_vertex(*n, i, j);
    }
    n->dirty = true;
  }
  check_device("terrain tile refinement");
}

std::size_t Scene::update_terrain(std::span<const HeightUpdate> updates) {
  std::size_t applied = 0;
  const int t = config_.terrain_tile_cells;
  for (const auto& u : updates) {
    if (!std::isfinite(u.height_m)) {
      throw std::invalid_argument("terrain update (" + std::to_string(u.i) + ", " +
                                  std::to_string(u.j) + "): height is not finite");
    }
    if (u.i < 0 || u.j < 0 || u.i >= grid_.nx || u.j >= grid_.ny) continue;
    grid_.at(u.i, u.j) = static_cast<float>(u.height_m);
    ++applied;
    // A vertex on a tile border belongs to up to four tiles.
    const int tx1 = std::min(u.i / t, tiles_x_ - 1), ty1 = std::min(u.j / t, tiles_y_ - 1);
    const int tx0 = (u.i % t == 0 && u.i > 0) ? tx1 - 1 : tx1;
    const int ty0 = (u.j % t == 0 && u.j > 0) ? ty1 - 1 : ty1;
    for (int ty = ty0; ty <= ty1; ++ty) {
      for (int tx = tx0; tx <= tx1; ++tx) {
        Tile& tile = tiles_[static_cast<std::size_t>(ty) * tiles_x_ + tx];
        if (u.i < tile.i0 || u.i > tile.i0 + tile.cells_x || u.j < tile.j0 ||
            u.j > tile.j0 + tile.cells_y) {
          continue;
        }
        if (tile.step != 1) {
          refine_tile(tile);
        } else if (!tile.fresh) {  // a fresh tile gets every height in commit()
          write_tile_vertex(tile, u.i, u.j);
          tile.dirty = true;
        }
        dirty_ = true;
      }
    }
  }
  return applied;
}

std::size_t Scene::update_terrain_world(std::span<const HeightUpdate> updates) {
  const double fi = grid_.origin.x() / grid_.spacing_m, fj = grid_.origin.y() / grid_.spacing_m;
  const double ri = std::round(fi), rj = std::round(fj);
  if (std::abs(fi - ri) > 1e-6 || std::abs(fj - rj) > 1e-6) {
    throw std::logic_error("terrain grid origin is not on the world-anchored grid");
  }
  const auto i0 = static_cast<std::int32_t>(ri), j0 = static_cast<std::int32_t>(rj);
  std::vector<HeightUpdate> local(updates.begin(), updates.end());
  for (auto& u : local) {
    u.i -= i0;
    u.j -= j0;
  }
  return update_terrain(local);
}

void Scene::add_obstacle(const world::Obstacle& obstacle, std::optional<Rgb> colour) {
  Surface surface;
  surface.kind = SurfaceKind::obstacle;
  surface.label = obstacle.label;
  surface.colour = colour.value_or(obstacle_colour(obstacle.label));
  surface.reflectance = config_.obstacle_reflectance;
  const Pose& pose = obstacle.pose;
  RTCGeometry g = nullptr;
  if (const TriMesh* m = mesh(obstacle.label)) {
    const double r = obstacle.size.x();
    const Vec3 half = obstacle.shape == world::ShapeKind::box      ? obstacle.size
                      : obstacle.shape == world::ShapeKind::sphere ? Vec3(r, r, r)
                                                                   : Vec3(r, r, obstacle.size.z());
    const TriMesh fitted = fit_to_box(*m, -half, half);
    float* v = nullptr;
    g = make_mesh(device_, fitted.vertices.size(), fitted.triangles, &v);
    for (std::size_t k = 0; k < fitted.vertices.size(); ++k) {
      store(v, k, pose.position + pose.orientation * fitted.vertices[k]);
    }
    surface.prim_part = fitted.parts;
    surface.part_colours = colour ? std::vector<Rgb>(fitted.part_colours.size(), *colour)
                                  : fitted.part_colours;
    surface.part_reflectances.assign(fitted.part_colours.size(), surface.reflectance);
    primitive_count_ += fitted.triangles.size();
    rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
    attach(g, surface);
    check_device("obstacle mesh creation");
    return;
  }
  switch (obstacle.shape) {
    case world::ShapeKind::sphere: {
      g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_SPHERE_POINT);
      auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
          g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), 1));
      v[0] = static_cast<float>(pose.position.x());
      v[1] = static_cast<float>(pose.position.y());
      v[2] = static_cast<float>(pose.position.z());
      v[3] = static_cast<float>(obstacle.size.x());
      primitive_count_ += 1;
      break;
    }
    case world::ShapeKind::box:
    case world::ShapeKind::cylinder: {
      std::vector<Vec3> local;
      std::vector<std::array<unsigned, 3>> tris;
      if (obstacle.shape == world::ShapeKind::box) {
        local = box_vertices(obstacle.size);
        box_triangles(0, tris);
      } else {
        local =
            cylinder_vertices(obstacle.size.x(), obstacle.size.z(), 2, config_.cylinder_segments);
        cylinder_triangles(0, config_.cylinder_segments, tris);
      }
      float* v = nullptr;
      g = make_mesh(device_, local.size(), tris, &v);
      for (std::size_t k = 0; k < local.size(); ++k) {
        store(v, k, pose.position + pose.orientation * local[k]);
      }
      primitive_count_ += tris.size();
      break;
    }
  }
  rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
  attach(g, surface);
  check_device("obstacle creation");
}

void Scene::add_obstacles(const world::Obstacles& obstacles) {
  for (const auto& o : obstacles) add_obstacle(o);
}

void Scene::add_vehicle(const std::string& id, const VehicleShape& shape) {
  if (vehicles_.contains(id)) throw std::invalid_argument("vehicle '" + id + "' already in scene");
  VehicleEntry e;
  e.shape = shape;
  std::vector<std::array<unsigned, 3>> tris;
  std::vector<std::uint8_t> parts;
  std::vector<Rgb> colours = {shape.body_colour, shape.wheel_colour, shape.hub_colour};
  const auto boxes = vehicle_body_boxes(shape);
  if (const TriMesh* m = mesh("vehicle_body")) {
    // Fitted to the boxes' bounding box; material "body" takes the vehicle's colour, the
    // others (glass, lights) keep theirs as parts 3, 4, ...
    Vec3 lo = boxes[0].centre - boxes[0].half_extents, hi = boxes[0].centre + boxes[0].half_extents;
    for (const DrawnBox& b : boxes) {
      lo = lo.cwiseMin(b.centre - b.half_extents);
      hi = hi.cwiseMax(b.centre + b.half_extents);
    }
    const TriMesh fitted = fit_to_box(*m, lo, hi);
    e.body_local = fitted.vertices;
    tris = fitted.triangles;
    if (fitted.part_colours.size() > 250) throw std::invalid_argument("vehicle_body.obj: too many materials");
    for (const std::uint8_t p : fitted.parts) {
      parts.push_back(fitted.part_names[p] == "body" ? static_cast<std::uint8_t>(VehiclePart::body)
                                                     : static_cast<std::uint8_t>(3 + p));
    }
    colours.insert(colours.end(), fitted.part_colours.begin(), fitted.part_colours.end());
  } else {
    for (const DrawnBox& b : boxes) {
      box_triangles(static_cast<unsigned>(e.body_local.size()), tris);
      for (const Vec3& v : box_vertices(b.half_extents)) e.body_local.push_back(b.centre + v);
    }
    parts.assign(tris.size(), static_cast<std::uint8_t>(VehiclePart::body));
  }
  const int seg = config_.cylinder_segments;
  e.wheel_local = wheel_vertices(shape.wheel_radius_m, 0.5 * shape.wheel_width_m, seg);
  const auto body_vertices = static_cast<unsigned>(e.body_local.size());
  const auto wheel_vertices = static_cast<unsigned>(e.wheel_local.size());
  for (unsigned w = 0; w < 4; ++w) wheel_triangles(body_vertices + w * wheel_vertices, seg, tris, parts);
  e.triangles = tris.size();
  e.geometry = make_mesh(device_, body_vertices + 4 * e.wheel_local.size(), tris, &e.vertices);
  rtcSetGeometryBuildQuality(e.geometry, RTC_BUILD_QUALITY_REFIT);
  // Slot: smallest free index (stable while the vehicle lives).
  auto it = std::find(used_slots_.begin(), used_slots_.end(), false);
  e.slot = static_cast<int>(it - used_slots_.begin());
  if (it == used_slots_.end()) {
    used_slots_.push_back(true);
  } else {
    *it = true;
  }
  rtcSetGeometryUserData(e.geometry, reinterpret_cast<void*>(static_cast<std::intptr_t>(e.slot)));
  rtcSetGeometryIntersectFilterFunction(e.geometry, hide_vehicle_filter);
  rtcSetGeometryOccludedFilterFunction(e.geometry, hide_vehicle_filter);
  Surface surface;
  surface.kind = SurfaceKind::vehicle;
  surface.colour = shape.body_colour;
  surface.reflectance = shape.body_reflectance;
  surface.prim_part = std::move(parts);
  surface.part_reflectances = {shape.body_reflectance, shape.wheel_reflectance,
                               shape.hub_reflectance};
  surface.part_reflectances.resize(colours.size(), shape.body_reflectance);
  surface.part_colours = std::move(colours);
  surface.vehicle_slot = e.slot;
  primitive_count_ += tris.size();
  auto [pos, inserted] = vehicles_.emplace(id, std::move(e));
  set_vehicle_pose(id, Pose{}, {});  // writes vertices
  RTCGeometry g = pos->second.geometry;
  rtcRetainGeometry(g);  // keep our handle valid after attach() releases its reference
  pos->second.id = attach(g, surface);
  vehicle_of_geometry_[pos->second.id] = &pos->second;
  check_device("vehicle creation");
}

void Scene::remove_vehicle(const std::string& id) {
  auto it = vehicles_.find(id);
  if (it == vehicles_.end()) return;
  detach(it->second.id);
  vehicle_of_geometry_.erase(it->second.id);
  rtcReleaseGeometry(it->second.geometry);
  used_slots_[static_cast<std::size_t>(it->second.slot)] = false;
  primitive_count_ -= it->second.triangles;
  vehicles_.erase(it);
}

void Scene::set_vehicle_pose(const std::string& id, const Pose& chassis,
                             std::span<const Pose> wheels) {
  auto it = vehicles_.find(id);
  if (it == vehicles_.end()) throw std::invalid_argument("no vehicle '" + id + "' in scene");
  auto finite = [](const Pose& p) {
    return p.position.allFinite() && p.orientation.coeffs().allFinite() &&
           std::abs(p.orientation.norm() - 1.0) < 1e-3;
  };
  if (!finite(chassis)) throw std::invalid_argument("vehicle '" + id + "': invalid chassis pose");
  for (const auto& w : wheels) {
    if (!finite(w)) throw std::invalid_argument("vehicle '" + id + "': invalid wheel pose");
  }
  VehicleEntry& e = it->second;
  e.chassis = chassis;
  const std::size_t body = e.body_local.size();
  for (std::size_t k = 0; k < body; ++k) {
    store(e.vertices, k, chassis.position + chassis.orientation * e.body_local[k]);
  }
  const std::size_t per_wheel = e.wheel_local.size();
  for (std::size_t w = 0; w < 4; ++w) {
    Pose wp;
    if (w < wheels.size()) {
      wp = wheels[w];
    } else {
      wp.position = chassis.position + chassis.orientation * e.shape.wheel_positions_m[w];
      wp.orientation = chassis.orientation;
    }
    for (std::size_t k = 0; k < per_wheel; ++k) {
      store(e.vertices, body + w * per_wheel + k, wp.position + wp.orientation * e.wheel_local[k]);
    }
  }
  rtcUpdateGeometryBuffer(e.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
  rtcCommitGeometry(e.geometry);
  dirty_ = true;
}

void Scene::set_vehicle_pose(const std::string& id, const vehicle::VehicleSnapshot& snapshot) {
  std::array<Pose, 4> wheels;
  const std::size_t n = std::min<std::size_t>(4, snapshot.wheels.size());
  for (std::size_t w = 0; w < n; ++w) wheels[w] = snapshot.wheels[w].pose;
  set_vehicle_pose(id, snapshot.pose, std::span<const Pose>(wheels.data(), n));
  set_vehicle_velocity(id, snapshot.linear_velocity, snapshot.angular_velocity);
}

void Scene::set_vehicle_velocity(const std::string& id, const Vec3& linear, const Vec3& angular) {
  auto it = vehicles_.find(id);
  if (it == vehicles_.end()) throw std::invalid_argument("no vehicle '" + id + "' in scene");
  if (!linear.allFinite() || !angular.allFinite()) {
    throw std::invalid_argument("vehicle '" + id + "': non-finite velocity");
  }
  it->second.linear_velocity = linear;
  it->second.angular_velocity = angular;
}

namespace {
Vec3 rigid_velocity(const Pose& chassis, const Vec3& linear, const Vec3& angular, const Vec3& p) {
  return linear + angular.cross(p - chassis.position);
}
}  // namespace

Vec3 Scene::point_velocity(unsigned geom_id, const Vec3& p) const {
  const auto it = vehicle_of_geometry_.find(geom_id);
  if (it == vehicle_of_geometry_.end()) return Vec3::Zero();
  const VehicleEntry& e = *it->second;
  return rigid_velocity(e.chassis, e.linear_velocity, e.angular_velocity, p);
}

Vec3 Scene::vehicle_point_velocity(const std::string& id, const Vec3& p) const {
  const auto it = vehicles_.find(id);
  if (it == vehicles_.end()) return Vec3::Zero();
  const VehicleEntry& e = it->second;
  return rigid_velocity(e.chassis, e.linear_velocity, e.angular_velocity, p);
}

std::optional<Pose> Scene::vehicle_pose(const std::string& id) const {
  auto it = vehicles_.find(id);
  if (it == vehicles_.end()) return std::nullopt;
  return it->second.chassis;
}

Pose mounted_pose(const Scene& scene, const std::string& vehicle_id, const Pose& mount,
                  const std::string& sensor_id) {
  if (vehicle_id.empty()) return mount;
  const auto vehicle = scene.vehicle_pose(vehicle_id);
  if (!vehicle) {
    throw std::runtime_error(sensor_id + ": vehicle '" + vehicle_id + "' not in scene");
  }
  Pose p;
  p.position = vehicle->position + vehicle->orientation * mount.position;
  p.orientation = vehicle->orientation * mount.orientation;
  return p;
}

int Scene::vehicle_slot(const std::string& id) const {
  auto it = vehicles_.find(id);
  return it == vehicles_.end() ? -1 : it->second.slot;
}

void Scene::commit() {
  refit_tiles_last_commit_ = 0;
  bool fresh = false;
  for (auto& tile : tiles_) {
    fresh = fresh || tile.fresh;
    if (!tile.dirty) continue;
    rtcUpdateGeometryBuffer(tile.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(tile.geometry);
    tile.dirty = false;
    ++refit_tiles_last_commit_;
  }
  if (fresh) {
    // Tiles refined since the last commit: their BVHs are built over the flat layout, then
    // refit to the heights (see refine_tile()).
    rtcCommitScene(scene_);
    for (auto& tile : tiles_) {
      if (!tile.fresh) continue;
      for (int j = tile.j0; j <= tile.j0 + tile.cells_y; ++j) {
        for (int i = tile.i0; i <= tile.i0 + tile.cells_x; ++i) write_tile_vertex(tile, i, j);
      }
      rtcUpdateGeometryBuffer(tile.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
      rtcCommitGeometry(tile.geometry);
      tile.fresh = false;
      ++refit_tiles_last_commit_;
    }
  }
  rtcCommitScene(scene_);
  check_device("scene commit");
  dirty_ = false;
}

Rgb Scene::terrain_albedo(float x, float y) const {
  if (texture_.empty()) return look_.colour;
  const double s = look_.texture_size_m;
  double u = x / s, v = y / s;
  u -= std::floor(u);
  v -= std::floor(v);
  const double px = u * texture_width_ - 0.5, py = v * texture_height_ - 0.5;
  const double fx = std::floor(px), fy = std::floor(py);
  const float ax = static_cast<float>(px - fx), ay = static_cast<float>(py - fy);
  auto wrap = [](int i, int n) { return ((i % n) + n) % n; };
  const int x0 = wrap(static_cast<int>(fx), texture_width_), x1 = wrap(x0 + 1, texture_width_);
  const int y0 = wrap(static_cast<int>(fy), texture_height_), y1 = wrap(y0 + 1, texture_height_);
  auto texel = [&](int xi, int yi, int c) {
    return texture_[(static_cast<std::size_t>(yi) * texture_width_ + xi) * 3 + c];
  };
  float out[3];
  for (int c = 0; c < 3; ++c) {
    out[c] = (1 - ay) * ((1 - ax) * texel(x0, y0, c) + ax * texel(x1, y0, c)) +
             ay * ((1 - ax) * texel(x0, y1, c) + ax * texel(x1, y1, c));
  }
  return {out[0], out[1], out[2]};
}

}  // namespace syndds::sensors
