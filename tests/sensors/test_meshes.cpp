// Meshes from OBJ files (Assimp): the shipped config/meshes load with their materials, the scene
// draws obstacles and vehicle bodies with them inside the boxes the physics uses, the wheels
// stay in view, and rigs find the mesh directory (or say which one is missing).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <set>

#include "core/error.hpp"
#include "sensors/camera.hpp"
#include "sensors/mesh.hpp"
#include "sensors/rig_config.hpp"

#include "scene_fixture.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {

namespace fs = std::filesystem;
const std::string kMeshes = std::string(SYNDDS_TEST_CONFIG_DIR) + "/meshes";

fs::path mesh_temp_dir(const std::string& name) {
  auto p = fs::temp_directory_path() / ("syndds_meshes_" + name);
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

std::set<std::string> names(const TriMesh& m) {
  return {m.part_names.begin(), m.part_names.end()};
}

CameraConfig fixed_camera(const Vec3& position, double yaw, double pitch_down) {
  CameraConfig c;
  c.mode = CameraMode::fixed;
  c.intrinsics.width = 320;
  c.intrinsics.height = 180;
  c.noise = PixelNoiseModel::none;
  c.mount.pose.position = position;
  c.mount.pose.orientation =
      quat_from_yaw(yaw) * Quat(Eigen::AngleAxisd(pitch_down, Vec3::UnitY()));
  return c;
}

void flat_ground(Scene& scene) {
  scene.set_terrain(TerrainGrid::flat(Vec2(-30, -30), 0.5, 121, 121, 0.0), terrain_look("rigid"));
}

}  // namespace

TEST(Meshes, ShippedMeshesLoadWithTheirMaterials) {
  const std::vector<std::pair<std::string, std::set<std::string>>> want = {
      {"rock", {"rock"}},
      {"tree", {"bark", "foliage"}},
      {"bush", {"leaves"}},
      {"vehicle_body", {"body", "glass", "grille", "lights"}}};
  for (const auto& [name, materials] : want) {
    const std::string file = kMeshes + "/" + name + ".obj";
    EXPECT_LT(fs::file_size(file), 64u * 1024u) << file;  // small text files
    const TriMesh m = load_mesh(file);
    EXPECT_GT(m.triangles.size(), 10u) << name;
    ASSERT_EQ(m.parts.size(), m.triangles.size());
    for (const auto& t : m.triangles) {
      for (unsigned v : t) ASSERT_LT(v, m.vertices.size());
    }
    for (auto p : m.parts) ASSERT_LT(p, m.part_colours.size());
    std::set<std::string> used;
    for (auto p : m.parts) used.insert(m.part_names[p]);
    EXPECT_EQ(used, materials) << name;
    EXPECT_TRUE(((m.max - m.min).array() > 0.5).all()) << name;
  }
  // The tree: bark brown, foliage green (the MTL's Kd).
  const TriMesh tree = load_mesh(kMeshes + "/tree.obj");
  for (std::size_t k = 0; k < tree.part_names.size(); ++k) {
    if (tree.part_names[k] == "foliage") {
      EXPECT_GT(tree.part_colours[k].g, 2.0f * tree.part_colours[k].r);
    }
  }
  const TriMesh fitted = fit_to_box(tree, Vec3(-1, -2, 0), Vec3(1, 2, 6));
  EXPECT_TRUE(fitted.min.isApprox(Vec3(-1, -2, 0)));
  double zmax = -1e9;
  for (const auto& v : fitted.vertices) zmax = std::max(zmax, v.z());
  EXPECT_NEAR(zmax, 6.0, 1e-9);
  EXPECT_EQ(names(fitted), names(tree));

  const auto dir = mesh_temp_dir("bad");
  std::ofstream(dir / "broken.obj") << "v 0 0 0\nf 1 2 3\n";
  EXPECT_THROW(load_mesh((dir / "broken.obj").string()), std::invalid_argument);
  EXPECT_THROW(load_mesh((dir / "missing.obj").string()), std::invalid_argument);
}

// A tree (cylinder obstacle) drawn with tree.obj: bark and foliage colours, nothing outside the
// cylinder's bounding box; a rock (sphere) likewise; a label without a mesh stays a primitive.
TEST(Meshes, ObstaclesAreDrawnWithTheirMeshesInsideTheirBoxes) {
  SceneConfig config;
  config.mesh_dir = kMeshes;
  Scene scene(config);
  flat_ground(scene);
  world::Obstacles props(3);
  props[0].label = "tree";
  props[0].shape = world::ShapeKind::cylinder;
  props[0].size = Vec3(0.6, 0, 2.5);  // radius, half length
  props[0].pose.position = Vec3(10.0, 0.0, 2.5);
  props[1].label = "rock";
  props[1].shape = world::ShapeKind::sphere;
  props[1].size = Vec3(0.8, 0, 0);
  props[1].pose.position = Vec3(10.0, 4.0, 0.8);
  props[2].label = "wall";  // no wall.obj: a box
  props[2].shape = world::ShapeKind::box;
  props[2].size = Vec3(0.2, 1.0, 1.0);
  props[2].pose.position = Vec3(10.0, -4.0, 1.0);
  const std::size_t before = scene.primitive_count();
  scene.add_obstacles(props);
  scene.commit();
  const TriMesh tree = load_mesh(kMeshes + "/tree.obj");
  const TriMesh rock = load_mesh(kMeshes + "/rock.obj");
  EXPECT_EQ(scene.primitive_count() - before, tree.triangles.size() + rock.triangles.size() + 12);

  // Horizontal rays through a grid over each box's side: every hit lies in the box.
  for (const auto& o : props) {
    const Vec3 half = o.shape == world::ShapeKind::box ? o.size
                      : o.shape == world::ShapeKind::sphere
                          ? Vec3(o.size.x(), o.size.x(), o.size.x())
                          : Vec3(o.size.x(), o.size.x(), o.size.z());
    int hits = 0;
    for (int a = 0; a <= 40; ++a) {
      for (int b = 0; b <= 40; ++b) {
        const double y = o.pose.position.y() + (a / 20.0 - 1.0) * 1.2 * half.y();
        const double z = o.pose.position.z() + (b / 20.0 - 1.0) * 1.2 * half.z();
        const fixture::RayHit r = fixture::cast_ray(scene, Vec3(0, y, z), Vec3::UnitX());
        if (!r.hit() || scene.surface(r.geom).kind != SurfaceKind::obstacle) continue;
        ++hits;
        const Vec3 p(r.t, y, z);
        EXPECT_TRUE(((p - o.pose.position).cwiseAbs().array() <= half.array() + 1e-4).all())
            << o.label << " hit at " << p.transpose();
      }
    }
    EXPECT_GT(hits, 100) << o.label;
  }
  // Seen from the sunny (east) side: the tree shows foliage green and bark brown.
  CameraSensor cam(fixed_camera(Vec3(20.0, 0, 2.0), std::numbers::pi, -0.05), "", 1, 0.01);
  const RgbImage img = cam.capture(scene, 0);
  int green = 0, brown = 0;
  for (int v = 0; v < img.height; ++v) {
    for (int u = 0; u < img.width; ++u) {
      const auto* p = img.at(u, v);
      green += p[1] > p[0] + 30 && p[1] > p[2] + 30;
      brown += p[0] > p[1] + 10 && p[1] > p[2] + 10 && p[0] < 170;
    }
  }
  EXPECT_GT(green, 100);
  EXPECT_GT(brown, 5);
}

// vehicle_body.obj: fitted to the body boxes' bounding box, the material "body" in the
// vehicle's colour, glass in its own; the chase camera still sees both rear tyres.
TEST(Meshes, MeshBodyTakesTheVehicleColourAndLeavesTheWheelsInView) {
  SceneConfig config;
  config.mesh_dir = kMeshes;
  Scene scene(config);
  flat_ground(scene);
  VehicleShape shape;
  shape.body_colour = {0.9f, 0.05f, 0.05f};
  shape.wheel_colour = {0.05f, 0.8f, 0.05f};
  scene.add_vehicle("ego", shape);
  const Pose ego{Vec3(0.0, 0.0, 0.467), Quat::Identity()};
  scene.set_vehicle_pose("ego", ego, {});
  scene.commit();
  CameraSensor chase(fixture::chase_camera(320, 180), "ego", 1, 0.01);
  const RgbImage img = chase.capture(scene, 0);
  int red = 0, glass = 0, tyre_left = 0, tyre_right = 0;
  for (int v = 0; v < img.height; ++v) {
    for (int u = 0; u < img.width; ++u) {
      const auto* p = img.at(u, v);
      red += p[0] > 60 && p[0] > 2 * p[1] && p[0] > 2 * p[2];
      glass += p[0] < 60 && p[1] < 60 && p[2] < 70 && p[1] < p[0] + 10;
      if (p[1] > 40 && p[1] > 2 * p[0] && p[1] > 2 * p[2]) ++(u < img.width / 2 ? tyre_left : tyre_right);
    }
  }
  EXPECT_GT(red, 500);
  EXPECT_GT(glass, 20);  // the rear window
  EXPECT_GT(tyre_left, 15);
  EXPECT_GT(tyre_right, 15);
}

TEST(Meshes, RigsFindTheMeshDirectoryOrNameTheMissingOne) {
  const SensorRig rig = load_sensor_rig(sensor_rig_path("default", SYNDDS_TEST_CONFIG_DIR));
  ASSERT_FALSE(rig.scene.mesh_dir.empty());
  EXPECT_TRUE(fs::equivalent(rig.scene.mesh_dir, kMeshes));
  const auto dir = mesh_temp_dir("rig");
  std::ofstream(dir / "rig.yaml") << "name: r\nscene: {meshes: nowhere}\n"
                                     "sensors: [{id: gps, type: gps}]\n";
  try {
    load_sensor_rig((dir / "rig.yaml").string());
    FAIL() << "a missing mesh directory was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("rig.yaml:2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nowhere"), std::string::npos) << e.what();
  }
}
