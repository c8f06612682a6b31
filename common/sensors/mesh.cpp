#include "sensors/mesh.hpp"

#include <assimp/Importer.hpp>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <stdexcept>

namespace syndds::sensors {

TriMesh load_mesh(const std::string& file) {
  Assimp::Importer importer;
  // Only triangles survive (points and lines are dropped); node transforms are baked in.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* scene = importer.ReadFile(
      file, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_PreTransformVertices |
                aiProcess_SortByPType);
  if (!scene || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE)) {
    throw std::invalid_argument("mesh " + file + ": " + importer.GetErrorString());
  }
  if (scene->mNumMaterials > 255) {
    throw std::invalid_argument("mesh " + file + ": more than 255 materials");
  }
  TriMesh out;
  for (unsigned m = 0; m < scene->mNumMaterials; ++m) {
    const aiMaterial* mat = scene->mMaterials[m];
    aiString name;
    mat->Get(AI_MATKEY_NAME, name);
    aiColor3D kd(0.5f, 0.5f, 0.5f);
    mat->Get(AI_MATKEY_COLOR_DIFFUSE, kd);
    out.part_names.emplace_back(name.C_Str());
    out.part_colours.push_back({kd.r, kd.g, kd.b});
  }
  for (unsigned k = 0; k < scene->mNumMeshes; ++k) {
    const aiMesh* mesh = scene->mMeshes[k];
    if (!(mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    const auto base = static_cast<unsigned>(out.vertices.size());
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      const Vec3 q(p.x, p.y, p.z);
      if (!q.allFinite()) throw std::invalid_argument("mesh " + file + ": non-finite vertex");
      out.vertices.push_back(q);
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;
      out.triangles.push_back(
          {base + face.mIndices[0], base + face.mIndices[1], base + face.mIndices[2]});
      out.parts.push_back(static_cast<std::uint8_t>(mesh->mMaterialIndex));
    }
  }
  if (out.triangles.empty()) throw std::invalid_argument("mesh " + file + ": no triangles");
  if (out.part_colours.empty()) {
    out.part_names.emplace_back("default");
    out.part_colours.push_back({0.5f, 0.5f, 0.5f});
  }
  out.min = out.max = out.vertices.front();
  for (const auto& v : out.vertices) {
    out.min = out.min.cwiseMin(v);
    out.max = out.max.cwiseMax(v);
  }
  return out;
}

TriMesh fit_to_box(const TriMesh& mesh, const Vec3& lo, const Vec3& hi) {
  TriMesh out = mesh;
  const Vec3 size = mesh.max - mesh.min;
  for (auto& v : out.vertices) {
    for (int a = 0; a < 3; ++a) {
      const double t = size[a] > 0.0 ? (v[a] - mesh.min[a]) / size[a] : 0.5;
      v[a] = lo[a] + t * (hi[a] - lo[a]);
    }
  }
  out.min = lo;
  out.max = hi;
  return out;
}

}  // namespace syndds::sensors
