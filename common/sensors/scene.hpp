#pragma once
// What the camera, lidar and radar see, held in an Embree 3 scene:
//  - terrain: a regular height grid cut into square tiles of quads, one Embree geometry per
//    tile; update_terrain() rewrites the changed vertices and marks only their tiles, which
//    commit() refits (build quality REFIT) - ruts from deformable soil cost a few tiles.
//    With a coarse stride, tiles nothing changed are drawn from every stride-th vertex and a
//    tile is redrawn at the grid's own spacing once one of its vertices changes (ruts at the
//    soil's resolution, untouched ground cheap);
//  - static obstacles: box (12 triangles), sphere (exact Embree sphere point), cylinder
//    (triangulated, 32 sides by default);
//  - vehicles: one triangle mesh each (a body of three boxes that leaves the wheels in view,
//    four wheels with tread, sidewalls and a spoked hub) whose vertices are rewritten from the
//    chassis and wheel poses every frame and refit.
// The scene is DYNAMIC (Embree's two-level build): commit() rebuilds only what changed plus
// the small top level. Renderers only read the scene; commit() before rendering.
#include <embree3/rtcore.h>

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/math.hpp"
#include "sensors/mesh.hpp"
#include "sensors/sensor_config.hpp"
#include "terrain/terrain.hpp"
#include "vehicle/vehicle_model.hpp"
#include "vehicle/vehicle_params.hpp"
#include "world/obstacle.hpp"

namespace syndds::sensors {


/// Regular height grid: vertex (i, j) at (origin.x + i * spacing, origin.y + j * spacing).
struct TerrainGrid {
  Vec2 origin = Vec2::Zero();
  double spacing_m = 0.1;
  int nx = 0;                  // vertices along x
  int ny = 0;                  // vertices along y
  std::vector<float> heights;  // nx * ny, index j * nx + i

  static TerrainGrid flat(const Vec2& origin, double spacing_m, int nx, int ny, double height_m);
  float& at(int i, int j) { return heights[static_cast<std::size_t>(j) * nx + i]; }
  float at(int i, int j) const { return heights[static_cast<std::size_t>(j) * nx + i]; }
};

/// One changed terrain vertex (as deformable terrain reports it).
struct HeightUpdate {
  std::int32_t i = 0;
  std::int32_t j = 0;
  double height_m = 0.0;
};

/// Grid sampled from any terrain surface over [x_min, x_max] x [y_min, y_max], anchored at
/// the world origin like the SCM grid (vertex (i, j) of the world grid at (i s, j s)), so
/// SCM vertex changes apply through Scene::update_terrain_world().
TerrainGrid sample_terrain(const terrain::TerrainSurface& surface, double spacing_m, double x_min,
                           double x_max, double y_min, double y_max);

/// How the terrain looks: a colour per terrain type or a tiled texture image.
struct TerrainLook {
  Rgb colour{0.5f, 0.5f, 0.5f};
  float reflectance = 0.3f;      // lidar reflectance
  std::string texture_file;      // optional image (PNG/JPEG), sRGB; replaces `colour`
  double texture_size_m = 10.0;  // ground size of one texture repeat
};

/// Presets: "rigid" (neutral grey), "silt" (brown, also "scm"/"soil"), "snow" (white).
/// Throws std::invalid_argument for other names.
TerrainLook terrain_look(std::string_view kind);

/// Drawable vehicle: chassis box and wheels (spin axis = wheel's local y).
/// Defaults: an HMMWV-class vehicle (config/vehicles/hmmwv.yaml).
struct VehicleShape {
  Vec3 half_extents_m = Vec3(2.35, 1.08, 0.55);
  Vec3 box_centre_m = Vec3(0.0, 0.0, 0.45);  // in the chassis reference frame
  double wheel_radius_m = 0.467;
  double wheel_width_m = 0.254;
  std::array<Vec3, 4> wheel_positions_m{// FL, FR, RL, RR: used when no wheel poses
                                        Vec3(1.689, 0.9095, 0.0), Vec3(1.689, -0.9095, 0.0),
                                        Vec3(-1.689, 0.9095, 0.0), Vec3(-1.689, -0.9095, 0.0)};
  Rgb body_colour{0.15f, 0.3f, 0.75f};
  Rgb wheel_colour{0.06f, 0.06f, 0.06f};  // tyre: tread and sidewalls
  Rgb hub_colour{0.55f, 0.55f, 0.52f};    // the hub's spokes (the gaps are tyre-coloured)
  float body_reflectance = 0.6f;
  float wheel_reflectance = 0.1f;
  float hub_reflectance = 0.5f;
};

/// One box of a drawn vehicle body, in the chassis reference frame.
struct DrawnBox {
  Vec3 centre = Vec3::Zero();
  Vec3 half_extents = Vec3::Zero();
};
/// The boxes a vehicle body is drawn with, inside the chassis box of `shape`: a hull between
/// the wheels (inner tyre faces less 3 cm) from the axle line up; a deck as wide and long as
/// the chassis box from 3 cm above the tyres; a cabin on the deck (rear 55 % to front 25 % of
/// the half length, 90 % of the width) up to the top of the chassis box. Seen from the side or
/// from behind, the wheels are not hidden.
std::array<DrawnBox, 3> vehicle_body_boxes(const VehicleShape& shape);

/// What each triangle of a vehicle mesh is (index into Surface::part_colours).
enum class VehiclePart : std::uint8_t { body = 0, tyre = 1, hub = 2 };
/// Hub pattern: 8 sectors around the axle, spokes (hub colour) and gaps (tyre colour)
/// alternating, so that a turning wheel visibly turns.
constexpr int kHubSectors = 8;
/// Hub radius as a share of the wheel radius.
constexpr double kHubRadiusShare = 0.6;

/// Shape from a vehicle definition (chassis box, wheel size, axle positions).
VehicleShape vehicle_shape(const vehicle::VehicleParams& params, const Rgb& body_colour);
/// Distinct body colours for vehicle index 0, 1, 2, ... (cycles after 8).
Rgb vehicle_palette(std::size_t index);
/// Default obstacle colours by label (rock, tree, bush, wall, ...; others orange).
Rgb obstacle_colour(std::string_view label);

class Scene;
/// World pose of a sensor mounted at `mount` (chassis frame) on vehicle `vehicle_id`; an empty
/// id: `mount` is the world pose. Throws std::runtime_error naming `sensor_id` when the vehicle
/// is not in the scene.
Pose mounted_pose(const Scene& scene, const std::string& vehicle_id, const Pose& mount,
                  const std::string& sensor_id);

/// Per-geometry surface data the renderers shade with.
enum class SurfaceKind : std::uint8_t { terrain, obstacle, vehicle };
struct Surface {
  SurfaceKind kind = SurfaceKind::terrain;
  Rgb colour;
  float reflectance = 0.5f;
  // Vehicles: a part per triangle (VehiclePart) with its colour and reflectance; empty:
  // `colour` and `reflectance` everywhere.
  std::vector<std::uint8_t> prim_part;
  std::vector<Rgb> part_colours;
  std::vector<float> part_reflectances;
  int vehicle_slot = -1;
  std::string label;  // obstacles: their label ("rock", ...; may be empty)

  Rgb colour_of(unsigned prim) const {
    return prim < prim_part.size() ? part_colours[prim_part[prim]] : colour;
  }
  float reflectance_of(unsigned prim) const {
    return prim < prim_part.size() ? part_reflectances[prim_part[prim]] : reflectance;
  }
};

/// Intersection context every renderer passes to Embree: vehicle geometries carry a filter
/// that drops hits on `hidden_slot` (a sensor does not see the vehicle it rides on).
struct HidingContext {
  RTCIntersectContext context;
  int hidden_slot = -1;
};
inline void init_hiding_context(HidingContext& c, int hidden_slot, bool coherent) {
  rtcInitIntersectContext(&c.context);
  c.context.flags =
      coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  c.hidden_slot = hidden_slot;
}

class Scene {
 public:
  explicit Scene(const SceneConfig& config = {});
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  const SceneConfig& config() const { return config_; }

  /// Replaces the terrain. `coarse_stride` > 1: a tile none of whose vertices has been changed
  /// by update_terrain() is drawn from every coarse_stride-th grid vertex (and its last row and
  /// column); the first change to one of its vertices redraws it at the grid's own spacing for
  /// good. Where such a fine tile borders a coarse one, its border vertices lie on the coarse
  /// tile's edges (no cracks). Throws std::invalid_argument on a malformed grid, a stride < 1
  /// or a texture that cannot be read.
  void set_terrain(const TerrainGrid& grid, const TerrainLook& look, int coarse_stride = 1);
  /// Applies changed heights; (i, j) index the grid from its origin. Returns how many were
  /// inside the grid (others are ignored). A non-finite height throws std::invalid_argument.
  std::size_t update_terrain(std::span<const HeightUpdate> updates);
  /// Same with (i, j) indexing the world-anchored grid (vertex at (i s, j s), SCM's
  /// convention). Throws std::logic_error if the grid origin is not a whole number of spacings.
  std::size_t update_terrain_world(std::span<const HeightUpdate> updates);
  const TerrainGrid& terrain() const { return grid_; }

  /// Adds a static obstacle; colour defaults to obstacle_colour(label). With a mesh directory
  /// (SceneConfig::mesh_dir) holding <label>.obj, the obstacle is drawn with that mesh fitted
  /// to its shape's bounding box (sphere: 2r cube; cylinder: 2r x 2r x its length; box: the
  /// box), in the mesh's material colours unless `colour` is given.
  void add_obstacle(const world::Obstacle& obstacle, std::optional<Rgb> colour = std::nullopt);
  void add_obstacles(const world::Obstacles& obstacles);

  /// Adds a vehicle (placed at the origin until posed). Throws if the id exists. With a mesh
  /// directory holding vehicle_body.obj, the body is that mesh fitted to the bounding box of
  /// vehicle_body_boxes() (its material "body" in the vehicle's colour, the others in theirs).
  void add_vehicle(const std::string& id, const VehicleShape& shape);
  void remove_vehicle(const std::string& id);
  bool has_vehicle(const std::string& id) const { return vehicles_.contains(id); }
  /// Poses a vehicle: chassis reference frame + wheel centres (empty: nominal positions).
  /// Non-finite positions or non-unit quaternions throw std::invalid_argument.
  void set_vehicle_pose(const std::string& id, const Pose& chassis, std::span<const Pose> wheels);
  void set_vehicle_pose(const std::string& id, const vehicle::VehicleSnapshot& snapshot);
  std::optional<Pose> vehicle_pose(const std::string& id) const;
  /// Sets a vehicle's velocities (world frame; linear of the chassis reference point), which
  /// radars see as Doppler (zero until set). Non-finite values throw std::invalid_argument.
  void set_vehicle_velocity(const std::string& id, const Vec3& linear, const Vec3& angular);
  /// Velocity (world frame) of the surface point `p` of geometry `geom_id`: the rigid motion
  /// of its vehicle's chassis (wheel spin is not added), zero for terrain and obstacles.
  Vec3 point_velocity(unsigned geom_id, const Vec3& p) const;
  /// Velocity of the point `p` rigidly attached to vehicle `id` (zero for an unknown id).
  Vec3 vehicle_point_velocity(const std::string& id, const Vec3& p) const;
  /// Slot used to hide a vehicle from its own sensors (-1 if unknown).
  int vehicle_slot(const std::string& id) const;

  /// Rebuilds what changed (dirty terrain tiles, moved vehicles) and the top level.
  void commit();
  bool committed() const { return !dirty_; }

  // --- renderer interface -------------------------------------------------------------------
  RTCScene handle() const { return scene_; }
  const Surface& surface(unsigned geom_id) const { return surfaces_[geom_id]; }
  /// Terrain albedo at world (x, y): preset colour or texture (bilinear, tiled).
  Rgb terrain_albedo(float x, float y) const;
  std::size_t primitive_count() const { return primitive_count_; }
  std::size_t dirty_tiles_last_commit() const { return refit_tiles_last_commit_; }
  std::size_t terrain_tiles() const { return tiles_.size(); }
  /// Terrain tiles drawn at the grid's own spacing (all of them with coarse stride 1).
  std::size_t fine_terrain_tiles() const;

 private:
  struct Tile {
    RTCGeometry geometry = nullptr;
    unsigned id = 0;
    int tx = 0, ty = 0;  // tile column and row
    int i0 = 0, j0 = 0;  // first vertex
    int cells_x = 0, cells_y = 0;  // grid cells covered
    int step = 1;  // grid vertices between drawn vertices: 1 (fine) or the coarse stride
    // Drawn vertices, row-major float3: column k at grid vertex i0 + min(k step, cells_x)
    // (likewise rows), so a coarse tile keeps its last row and column.
    float* vertices = nullptr;
    bool dirty = false;
    bool fresh = false;  // refined since the last commit (built flat, heights written by commit)
  };
  struct VehicleEntry {
    RTCGeometry geometry = nullptr;
    unsigned id = 0;
    int slot = 0;
    VehicleShape shape;
    Pose chassis;
    Vec3 linear_velocity = Vec3::Zero();
    Vec3 angular_velocity = Vec3::Zero();
    std::vector<Vec3> body_local;   // body box corners in the chassis frame
    std::vector<Vec3> wheel_local;  // one wheel's vertices in the wheel frame
    std::size_t triangles = 0;
    float* vertices = nullptr;
  };

  unsigned attach(RTCGeometry geometry, const Surface& surface);
  void detach(unsigned id);
  void clear_terrain();
  Tile* tile_at(int tx, int ty);
  RTCGeometry make_tile_geometry(Tile& tile, bool flat);
  void refine_tile(Tile& tile);
  float drawn_height(const Tile& tile, int i, int j) const;
  void write_tile_vertex(Tile& tile, int i, int j);
  void check_device(const char* what) const;
  /// <mesh_dir>/<name>.obj, read once (nullptr without a mesh directory or such a file).
  const TriMesh* mesh(const std::string& name);

  SceneConfig config_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  std::vector<Surface> surfaces_;
  TerrainGrid grid_;
  TerrainLook look_;
  int tiles_x_ = 0, tiles_y_ = 0;
  int coarse_stride_ = 1;
  std::vector<Tile> tiles_;
  int texture_width_ = 0, texture_height_ = 0;
  std::vector<float> texture_;  // linear RGB
  std::map<std::string, VehicleEntry> vehicles_;
  std::map<unsigned, const VehicleEntry*> vehicle_of_geometry_;
  std::map<std::string, std::optional<TriMesh>> meshes_;
  std::vector<bool> used_slots_;
  std::size_t primitive_count_ = 0;
  std::size_t refit_tiles_last_commit_ = 0;
  bool dirty_ = true;
};

}  // namespace syndds::sensors
