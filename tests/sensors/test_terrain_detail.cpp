// Terrain drawn coarse until it deforms, then at the grid's own spacing (Scene::set_terrain with
// a coarse stride): ruts show every soil vertex (no staircase), the seams between coarse and
// fine tiles have no cracks, and what is drawn does not depend on the order tiles were refined.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "scene_fixture.hpp"
#include "sensors/camera.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {

constexpr double kSpacing = 0.05;  // the soil's spacing (SCM default)
constexpr int kStride = 2;         // untouched ground every 0.1 m

// Rolling ground (so that a fine tile's border vertices are not on a coarse edge by chance),
// 12.8 m square: 257 x 257 vertices, 4 x 4 tiles of 64 cells.
TerrainGrid ground() { return fixture::rolling_terrain(12.8, kSpacing, 0.4); }

// Flat ground, 12.8 m square, with a 3 cm bump per odd vertex index: the coarse drawing (even
// vertices) does not see the bumps, so a fine tile's border differs by centimetres from the
// coarse edge it meets.
TerrainGrid bumpy_ground() {
  TerrainGrid g = TerrainGrid::flat(Vec2(-6.4, -6.4), kSpacing, 257, 257, 0.0);
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) g.at(i, j) = 0.03f * static_cast<float>(i % 2 + j % 2);
  }
  return g;
}

// A rut 0.6 m wide from x = -2 to x = 2 (across the tile border at x = 0) whose depth
// alternates between neighbouring vertices (4 cm at even i, 10 cm at odd i): drawn every second
// vertex, the odd ones would vanish.
std::vector<HeightUpdate> zigzag_rut(const TerrainGrid& g, double x0 = -2.0, double x1 = 2.0) {
  std::vector<HeightUpdate> rut;
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const double x = g.origin.x() + i * g.spacing_m, y = g.origin.y() + j * g.spacing_m;
      if (x < x0 - 1e-9 || x > x1 + 1e-9 || std::abs(y - 0.5) > 0.3 + 1e-9) continue;
      rut.push_back({i, j, g.at(i, j) - (i % 2 ? 0.10 : 0.04)});
    }
  }
  return rut;
}

struct Hit {
  bool hit = false;
  float z = 0.0f;
  Vec3 normal = Vec3::Zero();
};

// Straight down through (x, y).
Hit probe(const Scene& scene, double x, double y) {
  const fixture::RayHit r = fixture::cast_ray(scene, Vec3(x, y, 10.0), Vec3(0, 0, -1));
  Hit h;
  h.hit = r.hit();
  h.z = 10.0f - r.t;
  h.normal = r.normal.normalized();
  return h;
}

}  // namespace

TEST(TerrainDetail, UntouchedTilesAreCoarseARutIsDrawnAtEverySoilVertex) {
  Scene scene;
  const TerrainGrid g = ground();
  scene.set_terrain(g, terrain_look("silt"), kStride);
  scene.commit();
  ASSERT_EQ(scene.terrain_tiles(), 16u);
  EXPECT_EQ(scene.fine_terrain_tiles(), 0u);
  EXPECT_EQ(scene.primitive_count(), 16u * 32u * 32u);  // a quarter of the grid's cells

  const auto rut = zigzag_rut(g);
  EXPECT_EQ(scene.update_terrain(rut), rut.size());
  scene.commit();
  // The rut spans x -2..2 (tile columns 1 and 2) and y 0.2..0.8 (tile row 2).
  EXPECT_EQ(scene.fine_terrain_tiles(), 2u);
  EXPECT_EQ(scene.primitive_count(), 14u * 32u * 32u + 2u * 64u * 64u);

  // Every rut vertex is drawn at its own height: the depth profile along the rut alternates
  // 4 / 10 cm from one soil vertex to the next (the coarse drawing would show a smooth 4 cm).
  const auto& drawn = scene.terrain();
  for (const auto& u : rut) {
    const double x = g.origin.x() + u.i * kSpacing, y = g.origin.y() + u.j * kSpacing;
    // A hair off the vertex (exactly on it the ray meets four quads' shared corner).
    const Hit h = probe(scene, x + 1e-4, y + 1e-4);
    ASSERT_TRUE(h.hit) << x << ", " << y;
    EXPECT_NEAR(h.z, u.height_m, 2e-3) << "vertex " << u.i << ", " << u.j;
    EXPECT_FLOAT_EQ(drawn.at(u.i, u.j), static_cast<float>(u.height_m));
  }
  // Slopes between neighbouring vertices: 6 cm over 5 cm, down then up (a step every 0.1 m
  // would give flat facets at one depth).
  const int jm = static_cast<int>(std::lround((0.5 - g.origin.y()) / kSpacing));
  int down = 0, up = 0;
  for (int i = 0; i < g.nx; ++i) {
    const double x = g.origin.x() + (i + 0.5) * kSpacing, y = g.origin.y() + jm * kSpacing + 1e-3;
    if (x < -1.9 || x > 1.9) continue;
    const Hit h = probe(scene, x, y);
    ASSERT_TRUE(h.hit);
    const double base_slope =
        (g.at(i + 1, jm) - g.at(i, jm)) / kSpacing;  // the rolling ground's own slope
    const double dzdx = -h.normal.x() / h.normal.z() - base_slope;
    if (dzdx > 1.0) ++up;      // from an even (4 cm) to an odd (10 cm) vertex... or back
    if (dzdx < -1.0) ++down;
  }
  EXPECT_GE(up, 35);
  EXPECT_GE(down, 35);

  // Outside the rut the ground is still the grid's (coarse tiles meet the grid at their
  // vertices, and lie between them on straight lines).
  const Hit far = probe(scene, 5.0 + 1e-4, -5.0 + 1e-4);
  const int fi = static_cast<int>(std::lround((5.0 - g.origin.x()) / kSpacing));
  const int fj = static_cast<int>(std::lround((-5.0 - g.origin.y()) / kSpacing));
  ASSERT_TRUE(far.hit);
  EXPECT_NEAR(far.z, g.at(fi, fj), 2e-3);
}

// Where a fine tile meets a coarse one, the fine tile's extra border vertices lie on the coarse
// edge. On the bumpy ground a fine tile drawing its border at the grid's heights would leave a
// 3 cm slot along each seam, through which low rays from the coarse side see the sky.
TEST(TerrainDetail, NoCracksBetweenFineAndCoarseTiles) {
  const TerrainGrid g = bumpy_ground();
  Scene scene;
  scene.set_terrain(g, terrain_look("silt"), kStride);
  // A change inside tile (2, 2) only (x, y 0..3.2 m; the change does not reach its borders):
  // its four neighbours stay coarse.
  scene.update_terrain(std::vector<HeightUpdate>{{150, 150, -0.05}});
  scene.commit();
  ASSERT_EQ(scene.fine_terrain_tiles(), 1u);
  int misses = 0;
  for (int k = 0; k <= 2000; ++k) {  // straight down along the seams
    const double s = 3.2 * k / 2000.0;
    for (const Vec2& p : {Vec2(0.0, s), Vec2(3.2, s), Vec2(s, 0.0), Vec2(s, 3.2)}) {
      misses += !probe(scene, p.x(), p.y()).hit;
    }
  }
  EXPECT_EQ(misses, 0);
  // Low cameras 2 m outside each seam, looking across it: every pixel whose ray meets the
  // ground plane inside the terrain sees ground, not sky.
  CameraConfig cfg;
  cfg.mode = CameraMode::fixed;
  cfg.intrinsics.width = 640;
  cfg.intrinsics.height = 360;
  cfg.noise = PixelNoiseModel::none;
  struct View {
    Vec3 position;
    double yaw;
  };
  for (const View& view : {View{Vec3(-2.0, 1.6, 0.25), 0.0}, View{Vec3(5.2, 1.6, 0.25), std::numbers::pi},
                           View{Vec3(1.6, -2.0, 0.25), std::numbers::pi / 2},
                           View{Vec3(1.6, 5.2, 0.25), -std::numbers::pi / 2}}) {
    cfg.mount.pose.position = view.position;
    cfg.mount.pose.orientation =
        quat_from_yaw(view.yaw) * Quat(Eigen::AngleAxisd(0.125, Vec3::UnitY()));
    CameraSensor cam(cfg, "", 1, 0.01);
    const RgbImage img = cam.capture(scene, 0);
    int sky = 0, ground = 0;
    for (int v = 0; v < img.height; ++v) {
      for (int u = 0; u < img.width; ++u) {
        const Vec3 d = cfg.mount.pose.orientation * cam.model().ray_direction(u + 0.5, v + 0.5);
        if (d.z() > -1e-3) continue;
        const Vec3 p = view.position - (view.position.z() / d.z()) * d;
        if (std::abs(p.x()) > 6.2 || std::abs(p.y()) > 6.2) continue;
        ++ground;
        const auto* px = img.at(u, v);
        sky += px[2] > px[0] + 20;  // the sky is blue, the silt brown
      }
    }
    EXPECT_GT(ground, 10000);
    EXPECT_EQ(sky, 0) << "view from " << view.position.transpose();
  }
}

// The tiles a rut refines, and the order it refines them in, do not change what is drawn:
// a scene refined frame by frame renders the same bytes as one given all the ruts at once
// (as a run resumed from a checkpoint is). On the bumpy ground, a fine tile that kept its border
// on the coarse edge after its neighbour was refined would show.
TEST(TerrainDetail, FramesDoNotDependOnTheOrderTilesWereRefined) {
  const TerrainGrid g = bumpy_ground();
  const auto rut = zigzag_rut(g, -5.0, 5.0);
  CameraConfig cfg;
  cfg.mode = CameraMode::fixed;
  cfg.intrinsics.width = 320;
  cfg.intrinsics.height = 180;
  cfg.noise = PixelNoiseModel::none;
  cfg.mount.pose.position = Vec3(-6.0, 0.0, 1.5);
  cfg.mount.pose.orientation = Quat(Eigen::AngleAxisd(0.25, Vec3::UnitY()));
  CameraSensor cam(cfg, "", 1, 0.01);

  Scene at_once;
  at_once.set_terrain(g, terrain_look("silt"), kStride);
  at_once.update_terrain(rut);
  at_once.commit();
  const RgbImage want = cam.capture(at_once, 0);

  for (bool backwards : {false, true}) {
    Scene stepwise;
    stepwise.set_terrain(g, terrain_look("silt"), kStride);
    stepwise.commit();
    // Ten "frames" of 1 m of rut each, west to east or east to west (tiles are 3.2 m wide:
    // fine tiles border coarse ones in between); each vertex first at a shallower depth.
    for (int f = 0; f < 10; ++f) {
      const int part = backwards ? 9 - f : f;
      std::vector<HeightUpdate> piece;
      for (const auto& u : rut) {
        const double x = g.origin.x() + u.i * kSpacing;
        if (std::clamp(static_cast<int>(std::floor(x + 5.0)), 0, 9) != part) continue;
        piece.push_back({u.i, u.j, u.height_m + 0.02});
        piece.push_back(u);
      }
      stepwise.update_terrain(piece);
      stepwise.commit();
      (void)cam.capture(stepwise, 0);  // rendered in between, as a run does
    }
    EXPECT_EQ(stepwise.fine_terrain_tiles(), at_once.fine_terrain_tiles());
    EXPECT_TRUE(cam.capture(stepwise, 0).pixels == want.pixels) << "backwards " << backwards;
  }
}
