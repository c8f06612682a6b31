#pragma once
// Triangle meshes read from files (Wavefront OBJ with its MTL, or any format Assimp 5 reads):
// what the scene draws obstacles and vehicle bodies with when a mesh directory is configured
// (SceneConfig::mesh_dir, docs/sensors.md "Meshes").
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.hpp"
#include "sensors/sensor_config.hpp"

namespace syndds::sensors {

struct TriMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<unsigned, 3>> triangles;
  std::vector<std::uint8_t> parts;       // per triangle: its material, index into the lists below
  std::vector<std::string> part_names;   // material names (OBJ `usemtl`)
  std::vector<Rgb> part_colours;         // diffuse colour (MTL Kd) of each material
  Vec3 min = Vec3::Zero(), max = Vec3::Zero();  // bounding box of the vertices
};

/// Reads every mesh of the file into one (node transforms applied, faces triangulated,
/// identical vertices joined). Throws std::invalid_argument naming the file if it cannot be
/// read, holds no triangle, has more than 255 materials or a non-finite vertex.
TriMesh load_mesh(const std::string& file);

/// The mesh with its bounding box mapped onto the box [lo, hi] (axis by axis).
TriMesh fit_to_box(const TriMesh& mesh, const Vec3& lo, const Vec3& hi);

}  // namespace syndds::sensors
