#include "scm/scm_images.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "record/run_files.hpp"

namespace syndds::scm {
namespace {

// Encoded in memory and written by the run-directory writer: every write checked, and a
// reader never sees half an image.
void write_png(const std::string& path, const cv::Mat& image) {
  std::vector<std::uint8_t> bytes;
  if (!cv::imencode(".png", image, bytes)) {
    throw std::runtime_error("write_terrain_images: cannot encode " + path);
  }
  record::write_file_atomically(
      path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace

std::optional<ImageRegion> deformed_region(const ScmTerrain& terrain, std::int32_t margin) {
  const ScmSnapshot snap = terrain.snapshot();
  if (snap.vertices.empty()) return std::nullopt;
  ImageRegion r{snap.vertices.front().i, snap.vertices.front().i, snap.vertices.front().j,
                snap.vertices.front().j};
  for (const auto& v : snap.vertices) {
    r.i_min = std::min(r.i_min, v.i);
    r.i_max = std::max(r.i_max, v.i);
    r.j_min = std::min(r.j_min, v.j);
    r.j_max = std::max(r.j_max, v.j);
  }
  r.i_min = std::max(terrain.i_min(), r.i_min - margin);
  r.i_max = std::min(terrain.i_max(), r.i_max + margin);
  r.j_min = std::max(terrain.j_min(), r.j_min - margin);
  r.j_max = std::min(terrain.j_max(), r.j_max + margin);
  return r;
}

TerrainImageInfo write_terrain_images(const ScmTerrain& terrain, const std::string& prefix,
                                      std::optional<ImageRegion> region) {
  TerrainImageInfo info;
  if (!region) region = deformed_region(terrain);
  if (!region) {
    const std::int32_t ic = terrain.i_min() + (terrain.i_max() - terrain.i_min()) / 2;
    const std::int32_t jc = terrain.j_min() + (terrain.j_max() - terrain.j_min()) / 2;
    region = ImageRegion{ic, ic, jc, jc};
  }
  const ImageRegion r = *region;
  if (r.i_max < r.i_min || r.j_max < r.j_min) {
    throw std::invalid_argument("write_terrain_images: empty region");
  }
  const std::int64_t w = static_cast<std::int64_t>(r.i_max) - r.i_min + 1;
  const std::int64_t h = static_cast<std::int64_t>(r.j_max) - r.j_min + 1;
  if (w > 32768 || h > 32768) throw std::invalid_argument("write_terrain_images: region too large");
  info.region = r;
  info.width_px = static_cast<int>(w);
  info.height_px = static_cast<int>(h);

  cv::Mat1d heights(info.height_px, info.width_px);
  cv::Mat1d ruts(info.height_px, info.width_px);
  double hmin = INFINITY, hmax = -INFINITY, dmax = 0.0;
  for (int row = 0; row < info.height_px; ++row) {
    const std::int32_t j = r.j_max - row;
    for (int col = 0; col < info.width_px; ++col) {
      const std::int32_t i = r.i_min + col;
      const double z = terrain.vertex_height(i, j);
      const double d = std::max(0.0, terrain.base_height(i, j) - z);
      heights(row, col) = z;
      ruts(row, col) = d;
      hmin = std::min(hmin, z);
      hmax = std::max(hmax, z);
      dmax = std::max(dmax, d);
    }
  }
  info.height_min_m = hmin;
  info.height_m_per_count = hmax > hmin ? (hmax - hmin) / 65535.0 : 0.0;
  info.rut_depth_max_m = dmax;
  info.rut_depth_m_per_count = dmax > 0.0 ? dmax / 65535.0 : 0.0;

  cv::Mat1w height_img(info.height_px, info.width_px);
  cv::Mat1w rut_img(info.height_px, info.width_px);
  for (int row = 0; row < info.height_px; ++row) {
    for (int col = 0; col < info.width_px; ++col) {
      const double hv = info.height_m_per_count > 0.0
                            ? (heights(row, col) - hmin) / info.height_m_per_count
                            : 0.0;
      const double dv =
          info.rut_depth_m_per_count > 0.0 ? ruts(row, col) / info.rut_depth_m_per_count : 0.0;
      height_img(row, col) = static_cast<std::uint16_t>(std::clamp(std::lround(hv), 0L, 65535L));
      rut_img(row, col) = static_cast<std::uint16_t>(std::clamp(std::lround(dv), 0L, 65535L));
    }
  }
  info.height_png = prefix + "_height.png";
  info.rut_png = prefix + "_rut.png";
  info.json = prefix + "_images.json";
  write_png(info.height_png, height_img);
  write_png(info.rut_png, rut_img);
  nlohmann::json j;
  // The images sit beside this file: names, not paths, so that the run directory can move and
  // the file is the same wherever the run was written.
  j["height_png"] = std::filesystem::path(info.height_png).filename().string();
  j["rut_png"] = std::filesystem::path(info.rut_png).filename().string();
  j["width_px"] = info.width_px;
  j["height_px"] = info.height_px;
  j["spacing_m"] = terrain.spacing();
  j["vertex_i_of_column0"] = r.i_min;
  j["vertex_j_of_row0"] = r.j_max;
  j["x_of_column0_m"] = r.i_min * terrain.spacing();
  j["y_of_row0_m"] = r.j_max * terrain.spacing();
  j["rows_go"] = "south (-y)";
  j["height_min_m"] = info.height_min_m;
  j["height_m_per_count"] = info.height_m_per_count;
  j["rut_depth_m_per_count"] = info.rut_depth_m_per_count;
  j["rut_depth_max_m"] = info.rut_depth_max_m;
  j["mapping"] =
      "height_m = height_min_m + value * height_m_per_count; rut_depth_m = value * "
      "rut_depth_m_per_count; rut depth = max(0, undeformed height - height)";
  record::write_file_atomically(info.json, j.dump(2) + "\n");
  return info;
}

}  // namespace syndds::scm
