#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "scene_fixture.hpp"
#include "sensors/camera.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {

constexpr double kFrame = 0.01;

Pose camera_at(const Vec3& position, double pitch_down_rad, double yaw_rad = 0.0) {
  Pose p;
  p.position = position;
  p.orientation = Quat(Eigen::AngleAxisd(yaw_rad, Vec3::UnitZ())) *
                  Quat(Eigen::AngleAxisd(pitch_down_rad, Vec3::UnitY()));
  return p;
}

CameraConfig fixed_camera(int w, int h, const Pose& pose) {
  CameraConfig c;
  c.mode = CameraMode::fixed;
  c.intrinsics.width = w;
  c.intrinsics.height = h;
  c.mount.pose = pose;
  c.noise = PixelNoiseModel::none;
  return c;
}

void flat_terrain(Scene& scene, const TerrainLook& look, double size_m = 60.0,
                  double spacing_m = 0.5) {
  const int n = static_cast<int>(std::lround(size_m / spacing_m)) + 1;
  scene.set_terrain(TerrainGrid::flat(Vec2(-0.5 * size_m, -0.5 * size_m), spacing_m, n, n, 0.0),
                    look);
}

// Red objects, lit or in shadow (shadowed faces keep the hue at lower brightness).
bool is_red(const std::uint8_t* p) { return p[0] > 30 && p[0] > 2 * p[1] && p[0] > 2 * p[2]; }
// Black tyres: even fully lit they stay below 80 after gamma (terrain in shadow is ~100).
bool is_dark(const std::uint8_t* p) { return p[0] < 80 && p[1] < 80 && p[2] < 80; }
bool is_blue(const std::uint8_t* p) { return p[2] > p[0] + 20; }

struct Box2 {
  double u0 = 1e9, v0 = 1e9, u1 = -1e9, v1 = -1e9;
  void add(double u, double v) {
    u0 = std::min(u0, u);
    v0 = std::min(v0, v);
    u1 = std::max(u1, u);
    v1 = std::max(v1, v);
  }
  bool empty() const { return u1 < u0; }
};

// Pixel-centre bounding box of the pixels that satisfy `pred`.
template <typename Pred>
Box2 pixel_box(const RgbImage& img, Pred&& pred, int* count = nullptr) {
  Box2 b;
  int n = 0;
  for (int v = 0; v < img.height; ++v) {
    for (int u = 0; u < img.width; ++u) {
      if (pred(img.at(u, v))) {
        b.add(u + 0.5, v + 0.5);
        ++n;
      }
    }
  }
  if (count) *count = n;
  return b;
}

// Expected 8-bit value of a lit, unshadowed flat surface of albedo `a` (see camera.hpp).
double flat_lit_value(float albedo, const SceneConfig& sc, double gamma = 2.2) {
  const double e =
      sc.sun_intensity * std::sin(deg_to_rad(sc.sun_elevation_deg)) + sc.ambient_intensity;
  return 255.0 * std::pow(std::min(1.0, albedo * e), 1.0 / gamma);
}

}  // namespace

TEST(CameraModel, ProjectionAndRayDirectionsAreInverse) {
  CameraIntrinsics in;
  in.width = 640;
  in.height = 360;
  in.hfov_rad = deg_to_rad(100.0);
  in.k1 = -0.12;
  in.k2 = 0.02;
  const CameraModel m(in);
  EXPECT_NEAR(m.focal_px(), 320.0 / std::tan(deg_to_rad(50.0)), 1e-9);
  for (const Vec2& px : {Vec2(320, 180), Vec2(10.5, 20.25), Vec2(639, 359), Vec2(400, 30)}) {
    const Vec3 d = m.ray_direction(px.x(), px.y());
    const auto back = m.project(5.0 * d);
    ASSERT_TRUE(back.has_value());
    EXPECT_LT((*back - px).norm(), 1e-6);
  }
  // The optical axis goes through the image centre; left of the axis is left in the image.
  EXPECT_LT((*m.project(Vec3(10, 0, 0)) - Vec2(320, 180)).norm(), 1e-12);
  EXPECT_LT(m.project(Vec3(10, 1, 0))->x(), 320.0);
  EXPECT_LT(m.project(Vec3(10, 0, 1))->y(), 180.0);
  EXPECT_FALSE(m.project(Vec3(-1, 0, 0)).has_value());
  in.k1 = -2.0;
  EXPECT_THROW(CameraModel{in}, std::invalid_argument);
}

// Terrain colour per type, checked against the closed-form shading of a flat lit surface.
TEST(Camera, TerrainColoursMatchShadingOracle) {
  for (const std::string kind : {"snow", "silt", "rigid"}) {
    Scene scene;
    const TerrainLook look = terrain_look(kind);
    flat_terrain(scene, look);
    scene.commit();
    CameraSensor cam(fixed_camera(160, 90, camera_at(Vec3(0, 0, 1.5), deg_to_rad(20))), "", 1,
                     kFrame);
    const RgbImage img = cam.capture(scene, 0);
    double mean[3] = {0, 0, 0};
    int n = 0;
    for (int v = 54; v < 90; ++v) {  // bottom 40 %: ground within 3 m of the camera
      for (int u = 0; u < 160; ++u, ++n) {
        for (int c = 0; c < 3; ++c) mean[c] += img.at(u, v)[c];
      }
    }
    for (double& m : mean) m /= n;
    const float albedo[3] = {look.colour.r, look.colour.g, look.colour.b};
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(mean[c], flat_lit_value(albedo[c], scene.config()), 0.6) << kind << " ch " << c;
    }
    if (kind == "snow") {
      EXPECT_GT(std::min({mean[0], mean[1], mean[2]}), 235.0);  // near white
    } else if (kind == "silt") {
      EXPECT_GT(mean[0], mean[1] + 20.0);  // brown: red > green > blue
      EXPECT_GT(mean[1], mean[2] + 20.0);
    } else {
      EXPECT_LT(std::max({mean[0], mean[1], mean[2]}) - std::min({mean[0], mean[1], mean[2]}), 1.0);
    }
  }
}

TEST(Camera, ObstacleLandsWherePinholeWithDistortionProjectsIt) {
  Scene scene;
  flat_terrain(scene, terrain_look("rigid"));
  world::Obstacle ball;
  ball.shape = world::ShapeKind::sphere;
  ball.pose.position = Vec3(15.0, 3.0, 2.0);
  ball.size = Vec3(1.0, 0, 0);
  scene.add_obstacle(ball, Rgb{0.9f, 0.05f, 0.05f});
  scene.commit();
  const Pose pose = camera_at(Vec3(0, 0, 1.5), 0.0);
  CameraConfig cfg = fixed_camera(320, 180, pose);
  cfg.intrinsics.k1 = -0.08;
  cfg.intrinsics.k2 = 0.01;
  CameraSensor cam(cfg, "", 1, kFrame);
  const RgbImage img = cam.capture(scene, 0);

  // Silhouette of the sphere: circle where the view cone touches it, projected point by point.
  const Vec3 c = pose.orientation.conjugate() * (ball.pose.position - pose.position);
  const double d = c.norm(), r = ball.size.x();
  const Vec3 axis = c / d;
  const Vec3 e1 = axis.cross(Vec3::UnitZ()).normalized(), e2 = axis.cross(e1);
  const Vec3 rim_centre = axis * (d - r * r / d);
  const double rim_radius = r * std::sqrt(1.0 - r * r / (d * d));
  Box2 predicted;
  for (int k = 0; k < 256; ++k) {
    const double a = 2.0 * std::numbers::pi * k / 256;
    const auto px =
        cam.model().project(rim_centre + rim_radius * (std::cos(a) * e1 + std::sin(a) * e2));
    predicted.add(px->x(), px->y());
  }
  int count = 0;
  const Box2 seen = pixel_box(img, is_red, &count);
  ASSERT_FALSE(seen.empty());
  // Pixel centres inside the silhouette lie within half a pixel of its bounding box.
  EXPECT_NEAR(seen.u0, predicted.u0, 1.0);
  EXPECT_NEAR(seen.u1, predicted.u1, 1.0);
  EXPECT_NEAR(seen.v0, predicted.v0, 1.0);
  EXPECT_NEAR(seen.v1, predicted.v1, 1.0);
  const auto centre = cam.model().project(c);
  EXPECT_TRUE(is_red(img.at(static_cast<int>(centre->x()), static_cast<int>(centre->y()))));
  // Area of an ellipse-like blob vs the box: a sanity bound on the shape.
  const double box_area = (predicted.u1 - predicted.u0) * (predicted.v1 - predicted.v0);
  EXPECT_NEAR(count, std::numbers::pi / 4.0 * box_area, 0.1 * box_area);
}

TEST(Camera, RutInTerrainChangesTheImageWhereItIs) {
  Scene scene;
  flat_terrain(scene, terrain_look("silt"), 30.0, 0.1);
  scene.commit();
  const Pose pose = camera_at(Vec3(0, 0, 1.5), deg_to_rad(20));
  CameraSensor cam(fixed_camera(160, 90, pose), "", 1, kFrame);
  const RgbImage before = cam.capture(scene, 0);

  // A rut 2 m long (x 4..6 m), 0.6 m wide (y -0.3..0.3 m), 0.15 m deep.
  std::vector<HeightUpdate> rut;
  const auto& g = scene.terrain();
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const double x = g.origin.x() + i * g.spacing_m, y = g.origin.y() + j * g.spacing_m;
      if (x >= 4.0 - 1e-9 && x <= 6.0 + 1e-9 && std::abs(y) <= 0.3 + 1e-9) {
        rut.push_back({i, j, -0.15});
      }
    }
  }
  EXPECT_EQ(scene.update_terrain(rut), rut.size());
  EXPECT_EQ(scene.update_terrain(std::vector<HeightUpdate>{{-1, 0, 1.0}, {0, 100000, 1.0}}), 0u);
  scene.commit();
  EXPECT_LE(scene.dirty_tiles_last_commit(), 4u);  // only the tiles under the rut are refit
  EXPECT_GE(scene.dirty_tiles_last_commit(), 1u);
  const RgbImage after = cam.capture(scene, 0);

  Box2 predicted;  // the rut's footprint (one cell of slope around it) at both depths
  for (double x : {3.9, 6.1}) {
    for (double y : {-0.4, 0.4}) {
      for (double z : {0.0, -0.15}) {
        const auto px =
            cam.model().project(pose.orientation.conjugate() * (Vec3(x, y, z) - pose.position));
        predicted.add(px->x(), px->y());
      }
    }
  }
  int changed = 0;
  Box2 seen;
  for (int v = 0; v < 90; ++v) {
    for (int u = 0; u < 160; ++u) {
      int diff = 0;
      for (int c = 0; c < 3; ++c)
        diff = std::max(diff, std::abs(before.at(u, v)[c] - after.at(u, v)[c]));
      if (diff > 8) {
        ++changed;
        seen.add(u + 0.5, v + 0.5);
      }
    }
  }
  EXPECT_GT(changed, 30);
  EXPECT_GE(seen.u0, predicted.u0 - 1.0);
  EXPECT_LE(seen.u1, predicted.u1 + 1.0);
  EXPECT_GE(seen.v0, predicted.v0 - 1.0);
  EXPECT_LE(seen.v1, predicted.v1 + 1.0);
}

TEST(Camera, AnotherVehiclePosedInViewAppears) {
  Scene scene;
  flat_terrain(scene, terrain_look("rigid"));
  VehicleShape shape;
  shape.body_colour = {0.9f, 0.05f, 0.05f};
  scene.add_vehicle("other", shape);
  scene.set_vehicle_pose("other", Pose{Vec3(500, 500, 0), Quat::Identity()}, {});
  scene.commit();
  const Pose pose = camera_at(Vec3(0, 0, 1.5), deg_to_rad(3));
  CameraSensor cam(fixed_camera(160, 90, pose), "", 1, kFrame);
  int count = 0;
  pixel_box(cam.capture(scene, 0), is_red, &count);
  EXPECT_EQ(count, 0);

  const Pose vehicle{Vec3(15.0, 0.0, 0.467), quat_from_yaw(std::numbers::pi / 2)};  // side on
  scene.set_vehicle_pose("other", vehicle, {});
  scene.commit();
  const RgbImage img = cam.capture(scene, 0);
  const Box2 seen = pixel_box(img, is_red, &count);
  Box2 predicted;
  for (const DrawnBox& b : vehicle_body_boxes(shape)) {
    for (int k = 0; k < 8; ++k) {
      const Vec3 corner = b.centre + Vec3((k & 1) ? 1 : -1, (k & 2) ? 1 : -1, (k & 4) ? 1 : -1)
                                         .cwiseProduct(b.half_extents);
      const Vec3 w = vehicle.position + vehicle.orientation * corner;
      const auto px = cam.model().project(pose.orientation.conjugate() * (w - pose.position));
      predicted.add(px->x(), px->y());
    }
  }
  EXPECT_GT(count, 60);
  EXPECT_NEAR(seen.u0, predicted.u0, 1.0);
  EXPECT_NEAR(seen.u1, predicted.u1, 1.0);
  EXPECT_NEAR(seen.v0, predicted.v0, 1.0);
  // The bottom of the hull is partly hidden behind the near wheels: only an upper bound there.
  EXPECT_LE(seen.v1, predicted.v1 + 1.0);
  // Wheels (dark) show below the body.
  int dark = 0;
  const Box2 wheels = pixel_box(img, is_dark, &dark);
  EXPECT_GT(dark, 10);
  EXPECT_GT(wheels.v1, seen.v1 - 1.0);
}

TEST(Camera, MountedCameraHidesItsOwnVehicleChaseCameraSeesIt) {
  Scene scene;
  flat_terrain(scene, terrain_look("rigid"));
  VehicleShape shape;  // blue body
  scene.add_vehicle("ego", shape);
  const Pose ego{Vec3(5.0, 2.0, 0.467), quat_from_yaw(0.3)};
  scene.set_vehicle_pose("ego", ego, {});
  scene.commit();

  CameraConfig cfg;
  cfg.intrinsics.width = 64;
  cfg.intrinsics.height = 36;
  cfg.noise = PixelNoiseModel::none;
  cfg.mount.pose.position = Vec3(0.0, 0.0, 0.6);  // inside the chassis box
  CameraSensor hidden(cfg, "ego", 1, kFrame);
  const RgbImage a = hidden.capture(scene, 0);
  // Same pose as a fixed camera with the vehicle gone: the same image except where the
  // vehicle's own shadow darkens the ground (it still casts one).
  CameraSensor reference(fixed_camera(64, 36, hidden.camera_pose(scene)), "", 1, kFrame);
  scene.set_vehicle_pose("ego", Pose{Vec3(500, 500, 0), Quat::Identity()}, {});
  scene.commit();
  const RgbImage r = reference.capture(scene, 0);
  int same = 0, darker = 0;
  for (std::size_t i = 0; i < a.pixels.size(); i += 3) {
    const bool equal = std::equal(&a.pixels[i], &a.pixels[i] + 3, &r.pixels[i]);
    same += equal;
    darker += !equal && a.pixels[i] < r.pixels[i] && a.pixels[i + 1] < r.pixels[i + 1] &&
              a.pixels[i + 2] < r.pixels[i + 2] && !is_blue(&a.pixels[i]);
  }
  EXPECT_GT(same, 64 * 36 / 2);
  EXPECT_EQ(same + darker, 64 * 36);

  scene.set_vehicle_pose("ego", ego, {});
  scene.commit();
  cfg.hide_own_vehicle = false;
  CameraSensor inside(cfg, "ego", 1, kFrame);
  int body = 0;
  pixel_box(
      inside.capture(scene, 0), [](const std::uint8_t* p) { return is_blue(p) || is_dark(p); },
      &body);
  EXPECT_EQ(body, 64 * 36);  // every ray hits the inside of the box (or a wheel in it)

  cfg.mode = CameraMode::chase;
  cfg.chase.target_height_m = 0.6;
  CameraSensor chase(cfg, "ego", 1, kFrame);
  const Pose cp = chase.camera_pose(scene);
  EXPECT_NEAR(yaw_of(cp.orientation), 0.3, 1e-9);
  EXPECT_NEAR((cp.position - ego.position).head<2>().norm(), cfg.chase.distance_m, 1e-9);
  const RgbImage c = chase.capture(scene, 0);
  EXPECT_TRUE(is_blue(c.at(32, 18)));  // the vehicle at the image centre
}

// The chase camera swung about the vehicle's vertical axis: at distance_m horizontally and
// height_m above the reference, in the direction azimuth_deg from straight behind towards the
// vehicle's left, looking at the target point (it projects to the image centre), upright.
// Azimuth 0 is the camera straight behind, computed as before the azimuth existed.
TEST(Camera, ChaseCameraPoseSwingsByItsAzimuth) {
  const CameraModel model(CameraIntrinsics{320, 180, deg_to_rad(70.0), 0.0, 0.0});
  for (const double yaw : {0.0, 0.7, -2.5}) {
    // A vehicle pitched and rolled a little: the camera follows the yaw only.
    const Pose vehicle{Vec3(12.0, -4.0, 0.6), quat_from_yaw(yaw) *
                                                  Quat(Eigen::AngleAxisd(0.05, Vec3::UnitY())) *
                                                  Quat(Eigen::AngleAxisd(-0.03, Vec3::UnitX()))};
    const double heading = yaw_of(vehicle.orientation);
    const Vec3 forward(std::cos(heading), std::sin(heading), 0.0);
    const Vec3 left(-forward.y(), forward.x(), 0.0);
    for (const double azimuth : {0.0, 35.0, 90.0, -60.0, 180.0}) {
      SCOPED_TRACE(testing::Message() << "yaw " << yaw << ", azimuth " << azimuth);
      ChaseConfig chase;
      chase.distance_m = 9.0;
      chase.height_m = 3.5;
      chase.target_height_m = 1.2;
      chase.azimuth_deg = azimuth;
      const Pose cp = chase_camera_pose(vehicle, chase);
      const Vec3 offset = cp.position - vehicle.position;
      EXPECT_NEAR(offset.z(), 3.5, 1e-12);
      EXPECT_NEAR(offset.head<2>().norm(), 9.0, 1e-12);
      // Straight behind, rotated towards the left by the azimuth.
      const double a = deg_to_rad(azimuth);
      const Vec3 expected_dir = -std::cos(a) * forward + std::sin(a) * left;
      EXPECT_NEAR((offset.head<2>() / 9.0 - expected_dir.head<2>()).norm(), 0.0, 1e-12);
      // Looking at the target: it projects to the image centre; the camera has no roll.
      const Vec3 target = vehicle.position + Vec3(0, 0, 1.2);
      const auto c = model.project(cp.orientation.conjugate() * (target - cp.position));
      ASSERT_TRUE(c.has_value());
      EXPECT_NEAR(c->x(), 160.0, 1e-9);
      EXPECT_NEAR(c->y(), 90.0, 1e-9);
      EXPECT_NEAR((cp.orientation * Vec3::UnitY()).z(), 0.0, 1e-12);
      EXPECT_GT((cp.orientation * Vec3::UnitZ()).z(), 0.0);
      if (azimuth == 90.0) {
        EXPECT_NEAR(offset.dot(left), 9.0, 1e-12);  // on the left side
      }
      if (azimuth == 0.0) {
        // Bit for bit the pose of the chase camera before azimuth_deg existed.
        Pose old;
        old.position = vehicle.position - 9.0 * forward + Vec3(0, 0, 3.5);
        const Vec3 x = (target - old.position).normalized();
        const Vec3 y = Vec3::UnitZ().cross(x).normalized();
        Eigen::Matrix3d r;
        r.col(0) = x;
        r.col(1) = y;
        r.col(2) = x.cross(y);
        old.orientation = Quat(r);
        EXPECT_TRUE(cp.position == old.position);
        EXPECT_TRUE(cp.orientation.coeffs() == old.orientation.coeffs());
      }
    }
  }
}

// The body does not hide the wheels: a chase camera (behind and above) sees both rear tyres
// beside the hull, below the deck; from the side the hubs show, and a wheel turned by half a
// hub sector looks different (spin is visible).
TEST(Camera, ChaseCameraSeesTheWheelsAndTheSideViewTheirHubsTurn) {
  Scene scene;
  flat_terrain(scene, terrain_look("rigid"));
  VehicleShape shape;  // HMMWV: chassis box 2.16 m wide, track 1.82 m: tyres inside the box
  shape.body_colour = {0.9f, 0.05f, 0.05f};   // red
  shape.wheel_colour = {0.05f, 0.8f, 0.05f};  // green tyres, to find them
  shape.hub_colour = {0.8f, 0.05f, 0.8f};     // magenta hubs
  auto green = [](const std::uint8_t* p) { return p[1] > 40 && p[1] > 2 * p[0] && p[1] > 2 * p[2]; };
  auto magenta = [](const std::uint8_t* p) {
    return p[0] > 40 && p[2] > 40 && p[0] > 2 * p[1] && p[2] > 2 * p[1];
  };
  scene.add_vehicle("ego", shape);
  const Pose ego{Vec3(3.0, -1.0, 0.467), quat_from_yaw(0.2)};
  scene.set_vehicle_pose("ego", ego, {});
  scene.commit();

  CameraSensor chase(fixture::chase_camera(320, 180), "ego", 1, kFrame);
  const RgbImage img = chase.capture(scene, 0);
  const Pose cp = chase.camera_pose(scene);
  // Tyre pixels around each rear wheel's projected centre (within one wheel radius).
  for (int w : {2, 3}) {  // rear left, rear right
    const Vec3 centre = ego.position + ego.orientation * shape.wheel_positions_m[w];
    const auto c = chase.model().project(cp.orientation.conjugate() * (centre - cp.position));
    const auto top = chase.model().project(
        cp.orientation.conjugate() * (centre + Vec3(0, 0, shape.wheel_radius_m) - cp.position));
    ASSERT_TRUE(c && top);
    const double r = c->y() - top->y();
    int tyre = 0;
    for (int v = 0; v < img.height; ++v) {
      for (int u = 0; u < img.width; ++u) {
        if (std::hypot(u + 0.5 - c->x(), v + 0.5 - c->y()) <= r) tyre += green(img.at(u, v));
      }
    }
    EXPECT_GT(tyre, 0.25 * r * r) << "rear wheel " << w << " hidden (radius " << r << " px)";
  }
  int body = 0;
  pixel_box(img, is_red, &body);
  EXPECT_GT(body, 500);  // and the vehicle is there

  // Side view (fixed camera 8 m to the vehicle's left, looking at it).
  const Vec3 left = ego.orientation * Vec3::UnitY();
  const Pose side{ego.position + 8.0 * left + Vec3(0, 0, 0.3),
                  quat_from_yaw(yaw_of(ego.orientation) - std::numbers::pi / 2) *
                      Quat(Eigen::AngleAxisd(0.04, Vec3::UnitY()))};
  CameraSensor side_cam(fixed_camera(320, 180, side), "", 1, kFrame);
  const RgbImage still = side_cam.capture(scene, 0);
  int hubs = 0;
  const Box2 hub_box = pixel_box(still, magenta, &hubs);
  EXPECT_GT(hubs, 40);
  // Both near wheels show their hubs: hub pixels at the two ends of the vehicle.
  EXPECT_GT(hub_box.u1 - hub_box.u0, 80.0);
  // Turn every wheel by 22.5 deg (half of one of the 8 hub sectors) about its axle.
  std::array<Pose, 4> wheels;
  for (int w = 0; w < 4; ++w) {
    wheels[w].position = ego.position + ego.orientation * shape.wheel_positions_m[w];
    wheels[w].orientation = ego.orientation * Quat(Eigen::AngleAxisd(0.3927, Vec3::UnitY()));
  }
  scene.set_vehicle_pose("ego", ego, wheels);
  scene.commit();
  const RgbImage turned = side_cam.capture(scene, 0);
  int turned_hubs = 0, swapped = 0;
  pixel_box(turned, magenta, &turned_hubs);
  for (int v = 0; v < still.height; ++v) {
    for (int u = 0; u < still.width; ++u) swapped += magenta(still.at(u, v)) != magenta(turned.at(u, v));
  }
  EXPECT_NEAR(turned_hubs, hubs, 0.2 * hubs);  // as much hub, elsewhere
  EXPECT_GT(swapped, hubs / 2);
}

TEST(Camera, NoiseStatisticsMatchConfiguration) {
  Scene scene;
  flat_terrain(scene, terrain_look("rigid"));
  scene.commit();
  const Pose down = camera_at(Vec3(0, 0, 3.0), std::numbers::pi / 2);  // uniform lit ground
  CameraConfig cfg = fixed_camera(160, 90, down);
  CameraSensor clean(cfg, "", 1, kFrame);
  const RgbImage ref = clean.capture(scene, 0);
  const double v0 = ref.pixels[0];
  for (auto p : ref.pixels) ASSERT_EQ(p, v0);
  EXPECT_NEAR(v0, flat_lit_value(0.5f, scene.config()), 0.6);

  struct Case {
    PixelNoiseModel model;
    double std, slope, intercept;
  };
  for (const Case k : {Case{PixelNoiseModel::gaussian, 0.02, 0, 0},
                       Case{PixelNoiseModel::pixel_dependent, 0, 0.004, 1e-4}}) {
    cfg.noise = k.model;
    cfg.noise_std = k.std;
    cfg.noise_slope = k.slope;
    cfg.noise_intercept = k.intercept;
    CameraSensor noisy(cfg, "", derive_seed(42, "lead/camera"), kFrame);
    const RgbImage img = noisy.capture(scene, 3);
    double sum = 0, sum2 = 0;
    for (auto p : img.pixels) {
      sum += p - v0;
      sum2 += (p - v0) * (p - v0);
    }
    const double n = static_cast<double>(img.pixels.size());
    const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
    const double expected = 255.0 * (k.model == PixelNoiseModel::gaussian
                                         ? k.std
                                         : std::sqrt(k.slope * v0 / 255.0 + k.intercept));
    EXPECT_NEAR(sd, expected, 0.05 * expected);
    EXPECT_NEAR(mean, 0.0, 4.0 * expected / std::sqrt(n) + 0.5);  // + quantisation of v0
    // Another frame index gives another pattern; the same index the same one.
    EXPECT_NE(noisy.capture(scene, 4).pixels, img.pixels);
    EXPECT_EQ(noisy.capture(scene, 3).pixels, img.pixels);
  }
}

TEST(Camera, DeterministicForOneTwoAndThreeThreads) {
  Scene scene;
  scene.set_terrain(fixture::rolling_terrain(60.0, 0.25, 1.0), terrain_look("silt"));
  scene.add_obstacles(fixture::scattered_obstacles(20, 60.0, 3));
  VehicleShape shape;
  scene.add_vehicle("a", shape);
  scene.set_vehicle_pose("a", Pose{Vec3(8, 0, 1.0), quat_from_yaw(0.4)}, {});
  scene.commit();
  for (int width : {160, 320}) {  // single-ray and packet paths
    std::vector<std::vector<std::uint8_t>> images;
    for (int threads : {1, 2, 3}) {
      CameraConfig cfg = fixed_camera(width, width * 9 / 16, camera_at(Vec3(-20, 0, 2), 0.1));
      cfg.noise = PixelNoiseModel::gaussian;
      cfg.noise_std = 0.01;
      cfg.threads = threads;
      CameraSensor cam(cfg, "", 77, kFrame);
      images.push_back(cam.capture(scene, 5).pixels);
    }
    EXPECT_EQ(images[0], images[1]);
    EXPECT_EQ(images[0], images[2]);
  }
}

// 30 Hz, lag 0.05 s, exposure 0.02 s rendered at its midpoint, fed every 10 ms frame.
TEST(CameraSensor, RateLagAndExposureOnTheFrameGrid) {
  Scene scene;
  flat_terrain(scene, terrain_look("rigid"));
  scene.add_vehicle("ego", VehicleShape{});
  CameraConfig cfg;
  cfg.intrinsics.width = 32;
  cfg.intrinsics.height = 18;
  cfg.mount.pose.position = Vec3(2.5, 0, 0.5);
  CameraSensor cam(cfg, "ego", 1, kFrame);
  cfg.exposure_mode = ExposureMode::average;
  cfg.subframes = 2;
  CameraSensor blur(cfg, "ego", 1, kFrame);

  std::vector<std::pair<double, CameraFrame>> seen, blurred;
  for (int f = 0; f <= 100; ++f) {
    const double t = f * kFrame;
    scene.set_vehicle_pose("ego", Pose{Vec3(10.0 * t, 0, 0.467), Quat::Identity()}, {});
    scene.commit();
    cam.update(scene, t);
    blur.update(scene, t);
    for (auto& fr : cam.take_available(t)) seen.emplace_back(t, std::move(fr));
    for (auto& fr : blur.take_available(t)) blurred.emplace_back(t, std::move(fr));
  }
  // Triggers at frames ceil(k * 10 / 3) = 0, 4, 7, ..., 94, 97; available 5 frames later.
  ASSERT_EQ(seen.size(), 29u);
  for (std::size_t k = 0; k < seen.size(); ++k) {
    const auto& [out_time, fr] = seen[k];
    const double trigger = std::ceil(static_cast<double>(k) * 10.0 / 3.0 - 1e-9) * kFrame;
    EXPECT_EQ(fr.stamp.sequence, k);
    EXPECT_NEAR(fr.stamp.time_s, trigger, 1e-12);
    EXPECT_NEAR(fr.stamp.available_s, trigger + 0.05, 1e-12);
    EXPECT_NEAR(out_time, fr.stamp.available_s, 1e-12);
    // Rendered at the exposure midpoint: one frame after the trigger.
    EXPECT_NEAR(fr.pose.position.x(), 10.0 * (trigger + 0.01) + 2.5, 1e-9);
    EXPECT_EQ(fr.image.width, 32);
  }
  EXPECT_EQ(cam.renders(), 30u);  // the 30th frame (trigger 97) is still in its lag
  ASSERT_EQ(blurred.size(), 29u);
  EXPECT_EQ(blur.renders(), 60u);  // two sub-frames per image (ticks +1 and +2)
  EXPECT_NEAR(blurred[3].second.pose.position.x(), 10.0 * (0.10 + 0.02) + 2.5, 1e-9);

  // The exposure window must fit in the period and in the lag.
  cfg.exposure_s = 0.08;
  EXPECT_THROW(CameraSensor(cfg, "ego", 1, kFrame), std::invalid_argument);
  cfg.exposure_s = 0.02;
  cfg.lag_s = 0.0;
  EXPECT_THROW(CameraSensor(cfg, "ego", 1, kFrame), std::invalid_argument);
}

// may_render(t) is true exactly in the frames whose update(scene, t) renders (the sensor agent
// commits the scene only then), for an exposure at the trigger, at its midpoint and averaged
// over sub-frames, with and without a frame filter.
TEST(CameraSensor, MayRenderExactlyWhenAnUpdateRenders) {
  Scene scene;
  flat_terrain(scene, terrain_look("rigid"));
  scene.add_vehicle("ego", VehicleShape{});
  for (int variant = 0; variant < 4; ++variant) {
    SCOPED_TRACE("variant " + std::to_string(variant));
    CameraConfig cfg;
    cfg.intrinsics.width = 16;
    cfg.intrinsics.height = 9;
    cfg.mount.pose.position = Vec3(2.5, 0, 0.5);
    if (variant == 0) cfg.exposure_s = 0.0;  // one render at the trigger
    if (variant == 2) {
      cfg.exposure_mode = ExposureMode::average;
      cfg.subframes = 3;
    }
    CameraSensor cam(cfg, "ego", 1, kFrame);
    // Variant 3: every other frame skipped by a filter.
    if (variant == 3) {
      cam.set_frame_filter([](std::int64_t available, std::int64_t) { return available % 2 == 0; });
    }
    int renders = 0;
    for (int f = 0; f <= 100; ++f) {
      const double t = f * kFrame;
      scene.set_vehicle_pose("ego", Pose{Vec3(10.0 * t, 0, 0.467), Quat::Identity()}, {});
      scene.commit();
      const bool may = cam.may_render(t);
      const auto before = cam.renders();
      cam.update(scene, t);
      EXPECT_EQ(may, cam.renders() > before) << "frame " << f;
      renders += cam.renders() > before;
      cam.take_available(t);
    }
    EXPECT_GE(renders, 10);
  }
}
