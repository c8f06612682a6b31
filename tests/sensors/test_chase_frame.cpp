// A chase-camera frame of a vehicle on rutted soil (docs/sensors.md, "A chase frame on rutted
// soil"). The full-dynamics HMMWV drives 3 s on SCM mid soil at 0.05 m, turning left, coupled
// to the soil as the vehicle member is; the soil's changes reach a sensors::Scene as they reach
// the sensor member's (SCM grid drawn with a coarse stride, tiles refined where the soil
// changed). The chase rig's camera renders it from a low rear three-quarter view. Checked:
//  - all four wheels are seen, each where rays from the camera to its tyre are not blocked;
//  - the ruts are drawn at the soil's own heights (every soil vertex, no staircase), which the
//    former drawing at every second vertex misses by centimetres;
//  - the frame shows the vehicle and the ruts.
// The frame is written to <build>/frames/chase_frame_ruts.png (docs/images/ holds a copy).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <vector>

#include "scm/scm_terrain.hpp"
#include "sensors/camera.hpp"
#include "sensors/rig_config.hpp"
#include "vehicle/ode_vehicle.hpp"

#include "scene_fixture.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {

const std::string kVehicle = "hmmwv";
constexpr double kSpacing = 0.05;    // the soil's (and the shipped scenarios') spacing
constexpr double kHalfSizeM = 50.0;  // soil area: 100 m x 100 m around the start
constexpr int kCoarseStride = 2;     // untouched soil drawn at 0.1 m, as the sensor member does
constexpr double kStepS = 0.002;     // dynamics step
constexpr int kStepsPerFrame = 5;    // 10 ms frames
constexpr double kDriveS = 3.0;
constexpr double kSpeedMps = 3.0;
constexpr double kSteering = 1.0;  // full lock to the left: the ruts curve across the view
constexpr double kStartYawDeg = -40.0;

// The view: 50 deg from straight behind towards the vehicle's left, 9 m away, 0.8 m above the
// chassis reference (about 1.2 m above the soil), looking at a point 1 m below the reference
// (more soil, less sky). The hull fills the space between the wheels from the axle line up and
// the deck covers them, so the far-side wheels show only under the hull, from low: from the
// chase rig's 3.5 m above the reference at 9 m, the far front wheel is hidden at every azimuth
// from 0 to 120 deg (no occlusion ray from the camera reaches a point on its tyre). Here both
// far wheels show in part (the pixel counts are printed).
ChaseConfig chase_view() {
  ChaseConfig c;
  c.azimuth_deg = 50.0;
  c.distance_m = 9.0;
  c.height_m = 0.8;
  c.target_height_m = -1.0;
  return c;
}

// Tyres and hubs in colours nothing else in the scene has.
bool is_tyre(const std::uint8_t* p) { return p[1] > 40 && p[1] > 2 * p[0] && p[1] > 2 * p[2]; }
bool is_hub(const std::uint8_t* p) {
  return p[0] > 40 && p[2] > 40 && p[0] > 2 * p[1] && p[2] > 2 * p[1];
}
bool is_wheel(const std::uint8_t* p) { return is_tyre(p) || is_hub(p); }

struct Hit {
  unsigned geom = RTC_INVALID_GEOMETRY_ID;
  float t = 0.0f;
  Vec3 point = Vec3::Zero();
};

Hit intersect(const Scene& scene, const Vec3& origin, const Vec3& dir) {
  const fixture::RayHit r = fixture::cast_ray(scene, origin, dir);
  Hit h;
  h.geom = r.geom;
  h.t = r.t;
  // The point as the renderer computes it (float origin + t dir).
  for (int k = 0; k < 3; ++k) {
    h.point[k] = static_cast<float>(origin[k]) + r.t * static_cast<float>(dir[k]);
  }
  return h;
}

// True if something in the scene lies on the segment from `origin` to `target` (less 2 mm).
bool occluded(const Scene& scene, const Vec3& origin, const Vec3& target) {
  const Vec3 d = target - origin;
  const double dist = d.norm();
  RTCRay ray{};
  ray.org_x = static_cast<float>(origin.x());
  ray.org_y = static_cast<float>(origin.y());
  ray.org_z = static_cast<float>(origin.z());
  ray.dir_x = static_cast<float>(d.x() / dist);
  ray.dir_y = static_cast<float>(d.y() / dist);
  ray.dir_z = static_cast<float>(d.z() / dist);
  ray.tfar = static_cast<float>(dist - 0.002);
  ray.mask = 0xFFFFFFFFu;
  HidingContext ctx;
  init_hiding_context(ctx, -1, false);
  rtcOccluded1(scene.handle(), &ctx.context, &ray);
  return ray.tfar < 0.0f;
}

// First intersection of a ray with a wheel's true shape, a solid cylinder (radius r, half
// width hw, axis = the wheel's local y), computed here without the scene.
std::optional<double> wheel_hit(const Pose& wheel, double r, double hw, const Vec3& origin,
                                const Vec3& dir) {
  const Vec3 o = wheel.orientation.conjugate() * (origin - wheel.position);
  const Vec3 d = wheel.orientation.conjugate() * dir;
  std::optional<double> best;
  auto keep = [&](double t) {
    if (t > 0.0 && (!best || t < *best)) best = t;
  };
  // Tread: (ox + t dx)^2 + (oz + t dz)^2 = r^2 with |y| <= hw.
  const double a = d.x() * d.x() + d.z() * d.z();
  const double b = 2.0 * (o.x() * d.x() + o.z() * d.z());
  const double c = o.x() * o.x() + o.z() * o.z() - r * r;
  const double disc = b * b - 4.0 * a * c;
  if (a > 1e-12 && disc >= 0.0) {
    for (const double s : {-1.0, 1.0}) {
      const double t = (-b + s * std::sqrt(disc)) / (2.0 * a);
      if (std::abs(o.y() + t * d.y()) <= hw) keep(t);
    }
  }
  // Sidewalls: y = +-hw within the radius.
  if (std::abs(d.y()) > 1e-12) {
    for (const double y : {-hw, hw}) {
      const double t = (y - o.y()) / d.y();
      const double x = o.x() + t * d.x(), z = o.z() + t * d.z();
      if (x * x + z * z <= r * r) keep(t);
    }
  }
  return best;
}

// The soil's height at (x, y) from its vertices at (i s, j s), each grid cell split into two
// triangles along the diagonal from (i+1, j) to (i, j+1) (as the scene splits its quads).
double soil_height(const scm::ScmTerrain& soil, double x, double y) {
  const double fx = x / kSpacing, fy = y / kSpacing;
  const auto i = static_cast<std::int32_t>(std::floor(fx));
  const auto j = static_cast<std::int32_t>(std::floor(fy));
  const double u = fx - i, v = fy - j;
  const double h00 = soil.vertex_height(i, j), h10 = soil.vertex_height(i + 1, j);
  const double h01 = soil.vertex_height(i, j + 1), h11 = soil.vertex_height(i + 1, j + 1);
  if (u + v <= 1.0) return h00 + u * (h10 - h00) + v * (h01 - h00);
  return h11 + (1.0 - u) * (h01 - h11) + (1.0 - v) * (h10 - h11);
}

// A rut: a soil cell with a corner more than 1 cm below the undeformed soil.
bool in_rut(const scm::ScmTerrain& soil, double x, double y) {
  const auto i = static_cast<std::int32_t>(std::floor(x / kSpacing));
  const auto j = static_cast<std::int32_t>(std::floor(y / kSpacing));
  for (const auto& [di, dj] : {std::pair{0, 0}, {1, 0}, {0, 1}, {1, 1}}) {
    if (soil.vertex_height(i + di, j + dj) < soil.base_height(i + di, j + dj) - 0.01) return true;
  }
  return false;
}

// No soil vertex of the cell ever deformed.
bool untouched(const scm::ScmTerrain& soil, double x, double y) {
  const auto i = static_cast<std::int32_t>(std::floor(x / kSpacing));
  const auto j = static_cast<std::int32_t>(std::floor(y / kSpacing));
  for (const auto& [di, dj] : {std::pair{0, 0}, {1, 0}, {0, 1}, {1, 1}}) {
    if (soil.vertex(i + di, j + dj)) return false;
  }
  return true;
}

// Heights drawn where the camera sees ruts, against the soil's own (soil_height).
struct RutHeights {
  int pixels = 0;
  double max_error_m = 0.0;
  double mean_error_m = 0.0;
  double max_bilinear_m = 0.0;  // against ScmTerrain::height (bilinear within a cell)
  // With an image of the scene: the sum of R, G and B of each rut pixel and of each pixel of
  // soil no vertex of which changed.
  std::vector<int> rut_values, untouched_values;
};

RutHeights rut_heights(const Scene& scene, const scm::ScmTerrain& soil, const CameraModel& model,
                       const Pose& camera, const RgbImage* image = nullptr) {
  RutHeights out;
  const int w = model.intrinsics().width, h = model.intrinsics().height;
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const Vec3 dir = camera.orientation * model.ray_direction(u + 0.5, v + 0.5);
      const Hit hit = intersect(scene, camera.position, dir);
      if (hit.geom == RTC_INVALID_GEOMETRY_ID) continue;
      if (scene.surface(hit.geom).kind != SurfaceKind::terrain) continue;
      const double x = hit.point.x(), y = hit.point.y();
      const auto value = [&] {
        const std::uint8_t* p = image->at(u, v);
        return p[0] + p[1] + p[2];
      };
      if (image && untouched(soil, x, y)) out.untouched_values.push_back(value());
      if (!in_rut(soil, x, y)) continue;
      if (image) out.rut_values.push_back(value());
      const double e = std::abs(hit.point.z() - soil_height(soil, x, y));
      ++out.pixels;
      out.max_error_m = std::max(out.max_error_m, e);
      out.mean_error_m += e;
      out.max_bilinear_m =
          std::max(out.max_bilinear_m, std::abs(hit.point.z() - soil.height(x, y)));
    }
  }
  if (out.pixels > 0) out.mean_error_m /= out.pixels;
  return out;
}

void write_frame(const std::filesystem::path& path, const RgbImage& img) {
  std::filesystem::create_directories(path.parent_path());
  cv::Mat bgr(img.height, img.width, CV_8UC3);
  for (int v = 0; v < img.height; ++v) {
    for (int u = 0; u < img.width; ++u) {
      const std::uint8_t* p = img.at(u, v);
      bgr.at<cv::Vec3b>(v, u) = cv::Vec3b(p[2], p[1], p[0]);
    }
  }
  ASSERT_TRUE(cv::imwrite(path.string(), bgr, {cv::IMWRITE_PNG_COMPRESSION, 9})) << path;
}

}  // namespace

TEST(ChaseFrame, HmmwvOnRuttedSoilShowsFourWheelsAndRutsWithoutSteps) {
  const SensorRig rig = load_sensor_rig(sensor_rig_path("chase", SYNDDS_TEST_CONFIG_DIR));
  ASSERT_FALSE(rig.scene.mesh_dir.empty());  // the shipped rig draws the body with its mesh
  ASSERT_EQ(rig.cameras.size(), 1u);

  scm::ScmParams sp;
  sp.soil = scm::soil_preset("mid");
  sp.grid.spacing_m = kSpacing;
  sp.grid.x_min_m = sp.grid.y_min_m = -kHalfSizeM;
  sp.grid.x_max_m = sp.grid.y_max_m = kHalfSizeM;
  auto soil = std::make_shared<scm::ScmTerrain>(sp);

  // The sensor member's scene: the undeformed soil grid drawn every second vertex until a
  // vertex of a tile changes, in the look of a firm soil (silt).
  Scene scene(rig.scene);
  scene.set_terrain(
      sample_terrain(*soil, kSpacing, -kHalfSizeM, kHalfSizeM, -kHalfSizeM, kHalfSizeM),
      terrain_look("silt"), kCoarseStride);
  const auto params =
      vehicle::load_vehicle_params(std::string(SYNDDS_TEST_CONFIG_DIR) + "/vehicles/hmmwv.yaml");
  const VehicleShape shape = vehicle_shape(params, vehicle_palette(0));
  scene.add_vehicle(kVehicle, shape);

  // Drive: settled on the soil, set rolling, speed held, full left lock. After each frame the
  // soil's changed vertices go to the scene at their levels (as TerrainDeformation messages
  // reach the sensor member) with the vehicle's pose.
  vehicle::OdeVehicleModel model(
      params, Pose{Vec3::Zero(), quat_from_yaw(deg_to_rad(kStartYawDeg))}, soil, {}, soil);
  model.set_speed(kSpeedMps);
  const int frames = static_cast<int>(std::lround(kDriveS / (kStepS * kStepsPerFrame)));
  for (int f = 0; f < frames; ++f) {
    const auto s = model.snapshot();
    const double speed = s.linear_velocity.dot(s.pose.orientation * Vec3::UnitX());
    model.set_inputs({kSteering, std::clamp(0.5 * (kSpeedMps - speed), 0.0, 1.0), 0.0});
    for (int k = 0; k < kStepsPerFrame; ++k) model.advance(kStepS);
    std::vector<HeightUpdate> updates;
    for (const auto& c : soil->take_local_changes()) {
      if (const auto v = soil->vertex(c.i, c.j)) updates.push_back({c.i, c.j, v->level_m});
    }
    scene.update_terrain_world(updates);
    scene.set_vehicle_pose(kVehicle, model.snapshot());
    scene.commit();
  }
  const vehicle::VehicleSnapshot end = model.snapshot();
  ASSERT_EQ(end.wheels.size(), 4u);
  double deepest = 0.0;
  for (const auto& v : soil->snapshot().vertices) {
    deepest = std::max(deepest, soil->base_height(v.i, v.j) - v.level_m);
  }
  std::printf(
      "[measured] after %.1f s: at (%.2f, %.2f), heading %.1f deg, %.2f m/s; %zu soil "
      "vertices changed, deepest rut %.3f m; %zu of %zu terrain tiles refined\n",
      kDriveS, end.pose.position.x(), end.pose.position.y(),
      rad_to_deg(yaw_of(end.pose.orientation)), end.speed_mps(), soil->stored_vertices(), deepest,
      scene.fine_terrain_tiles(), scene.terrain_tiles());
  ASSERT_GT(end.pose.position.norm(), 5.0);  // it drove (and left ruts behind)
  ASSERT_GT(scene.fine_terrain_tiles(), 0u);

  // ---- The frame, in the vehicle's colours ----------------------------------------------------
  CameraConfig camera = rig.cameras[0];
  camera.chase = chase_view();
  CameraSensor sensor(camera, kVehicle, 1, kStepS * kStepsPerFrame);
  const RgbImage frame = sensor.capture(scene, 0);
  const Pose cp = sensor.camera_pose(scene);
  const CameraModel& cam = sensor.model();
  const std::filesystem::path png =
      std::filesystem::path(SYNDDS_FRAMES_DIR) / "chase_frame_ruts.png";
  write_frame(png, frame);
  std::printf("[frame] %s (%d x %d)\n", png.string().c_str(), frame.width, frame.height);

  // ---- Four wheels --------------------------------------------------------------------------
  // The same scene with green tyres and magenta hubs. A pixel is expected to show wheel w when
  // its ray meets the wheel's true shape (a cylinder, computed here) and nothing in the scene
  // (soil, body, the other wheels) lies before that point; such pixels must be tyre or hub
  // coloured. A wheel the body hid would expect few pixels; one not drawn would match none.
  VehicleShape marked = shape;
  marked.wheel_colour = {0.05f, 0.8f, 0.05f};
  marked.hub_colour = {0.8f, 0.05f, 0.8f};
  scene.remove_vehicle(kVehicle);
  scene.add_vehicle(kVehicle, marked);
  scene.set_vehicle_pose(kVehicle, end);
  scene.commit();
  const RgbImage wheels_img = sensor.capture(scene, 0);
  const char* names[4] = {"front left", "front right", "rear left", "rear right"};
  const double r = shape.wheel_radius_m, hw = 0.5 * shape.wheel_width_m;
  for (int w = 0; w < 4; ++w) {
    const Pose& wp = end.wheels[static_cast<std::size_t>(w)].pose;
    const auto centre = cam.project(cp.orientation.conjugate() * (wp.position - cp.position));
    ASSERT_TRUE(centre.has_value());
    // Pixels within 1.5 projected radii of the centre (radius from the top of the tyre).
    const auto top =
        cam.project(cp.orientation.conjugate() * (wp.position + Vec3(0, 0, r) - cp.position));
    ASSERT_TRUE(top.has_value());
    const double rp = 1.5 * std::abs(centre->y() - top->y());
    int expected = 0, matched = 0, coloured = 0;
    for (int v = std::max(0, static_cast<int>(centre->y() - rp));
         v < std::min(wheels_img.height, static_cast<int>(centre->y() + rp) + 1); ++v) {
      for (int u = std::max(0, static_cast<int>(centre->x() - rp));
           u < std::min(wheels_img.width, static_cast<int>(centre->x() + rp) + 1); ++u) {
        if (std::hypot(u + 0.5 - centre->x(), v + 0.5 - centre->y()) > rp) continue;
        const Vec3 dir = cp.orientation * cam.ray_direction(u + 0.5, v + 0.5);
        const bool wheel_colour = is_wheel(wheels_img.at(u, v));
        coloured += wheel_colour;
        const auto t = wheel_hit(wp, r, hw, cp.position, dir);
        if (!t || occluded(scene, cp.position, cp.position + *t * dir)) continue;
        ++expected;
        matched += wheel_colour;
      }
    }
    std::printf(
        "[measured] %s wheel: %d pixels expected visible, %d of them tyre or hub "
        "coloured; %d wheel-coloured pixels within 1.5 radii of its centre\n",
        names[w], expected, matched, coloured);
    EXPECT_GT(expected, 400) << names[w] << " wheel hidden from this view";
    EXPECT_GE(matched, 0.95 * expected) << names[w] << " wheel not drawn where it is seen";
  }

  // ---- Ruts without steps --------------------------------------------------------------------
  // Every pixel that sees a rut (a cell of the soil with a corner more than 1 cm down): the
  // drawn height there against the soil's own triangles. Measured, max over about 24 000
  // pixels: 0 (float rounding, under 1e-5 m) drawn at every soil vertex; 0.040 m (mean
  // 0.013 m) drawn at every second vertex, the former drawing, rendered here for comparison
  // (the deformed grid given to a scene with no update, so that no tile is refined). Against
  // the soil's bilinear cells (ScmTerrain::height) instead of its triangles, the exact drawing
  // differs by up to 0.02 m: the two ways to fill a cell whose corners are not in a plane.
  const RutHeights drawn = rut_heights(scene, *soil, cam, cp, &frame);
  Scene stepped(rig.scene);
  stepped.set_terrain(sample_terrain(*soil, kSpacing, -10.0, 20.0, -10.0, 20.0),
                      terrain_look("silt"), kCoarseStride);
  stepped.add_vehicle(kVehicle, marked);
  stepped.set_vehicle_pose(kVehicle, end);
  stepped.commit();
  ASSERT_EQ(stepped.fine_terrain_tiles(), 0u);
  const RutHeights coarse = rut_heights(stepped, *soil, cam, cp);
  std::printf(
      "[measured] rut pixels drawn at every soil vertex: %d, height error max %.1e m, "
      "mean %.1e m (against bilinear cells: max %.4f m); drawn at every second vertex: "
      "%d, max %.4f m, mean %.4f m\n",
      drawn.pixels, drawn.max_error_m, drawn.mean_error_m, drawn.max_bilinear_m, coarse.pixels,
      coarse.max_error_m, coarse.mean_error_m);
  constexpr double kHeightTolM = 0.005;
  EXPECT_GT(drawn.pixels, 10000);
  EXPECT_LT(drawn.max_error_m, kHeightTolM) << "ruts not drawn at the soil's heights";
  // The check can tell: the staircase exceeds the tolerance.
  EXPECT_GT(coarse.max_error_m, 4.0 * kHeightTolM);

  // ---- Not an empty frame ------------------------------------------------------------------
  // The vehicle's blue body (lit or in shade; the sky is much less saturated), and ruts darker
  // than the lit untouched soil (the median value of soil no vertex of which changed).
  int body = 0;
  for (int v = 0; v < frame.height; ++v) {
    for (int u = 0; u < frame.width; ++u) {
      const std::uint8_t* p = frame.at(u, v);
      body += p[2] > p[0] + 60 && p[2] > p[1] + 40;
    }
  }
  ASSERT_GT(drawn.untouched_values.size(), 100000u);
  std::vector<int> soil_values = drawn.untouched_values;
  std::sort(soil_values.begin(), soil_values.end());
  const int lit_soil = soil_values[soil_values.size() / 2];
  const auto darker = std::count_if(drawn.rut_values.begin(), drawn.rut_values.end(),
                                    [&](int value) { return value < lit_soil - 30; });
  std::printf(
      "[measured] body pixels %d; lit soil %d (R + G + B); %zd of %zu rut pixels darker by "
      "more than 30\n",
      body, lit_soil, static_cast<std::ptrdiff_t>(darker), drawn.rut_values.size());
  EXPECT_GT(body, 10000);
  EXPECT_GT(static_cast<double>(darker), 0.5 * static_cast<double>(drawn.rut_values.size()));
}
