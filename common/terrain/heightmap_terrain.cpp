#include "terrain/heightmap_terrain.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string_view>
#include <vector>

#include "core/error.hpp"
#include "core/hash.hpp"

namespace syndds::terrain {
namespace {

std::vector<double> read_image_heights(const HeightmapSpec& spec, int& columns, int& rows) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(spec.image_file, ec)) {
    throw ConfigError(spec.image_file + ": cannot read height-map image (no such file)");
  }
  // One read: the bytes hashed against the fingerprint are the bytes decoded.
  std::ifstream in(spec.image_file, std::ios::binary);
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                         std::istreambuf_iterator<char>());
  if (!in.eof() && in.fail()) throw ConfigError(spec.image_file + ": cannot read height-map image");
  if (spec.image_hash != 0) {
    const std::uint64_t hash =
        fnv1a64(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
    if (hash != spec.image_hash) {
      throw ConfigError(spec.image_file + ": height-map image changed after the scenario was "
                        "loaded (the run's fingerprint has hash " + hex64(spec.image_hash) +
                        ", now " + hex64(hash) + ")");
    }
  }
  const cv::Mat img = bytes.empty() ? cv::Mat()
                                    : cv::imdecode(bytes, cv::IMREAD_ANYDEPTH | cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw ConfigError(spec.image_file + ": cannot read height-map image");
  double g_max = 0.0;
  if (img.depth() == CV_8U) {
    g_max = 255.0;
  } else if (img.depth() == CV_16U) {
    g_max = 65535.0;
  } else {
    throw ConfigError(spec.image_file + ": height map must be an 8 or 16-bit grey image");
  }
  if (img.cols < 2 || img.rows < 2) {
    throw ConfigError(spec.image_file + ": height map needs at least 2 x 2 pixels");
  }
  columns = img.cols;
  rows = img.rows;
  const double scale = (spec.max_height_m - spec.min_height_m) / g_max;
  std::vector<double> h(static_cast<std::size_t>(columns) * static_cast<std::size_t>(rows));
  for (int r = 0; r < rows; ++r) {
    const int j = rows - 1 - r;  // image row 0 is the north (max y) edge
    for (int i = 0; i < columns; ++i) {
      const double g = img.depth() == CV_8U ? img.at<std::uint8_t>(r, i)
                                            : img.at<std::uint16_t>(r, i);
      h[static_cast<std::size_t>(j) * static_cast<std::size_t>(columns) +
        static_cast<std::size_t>(i)] = spec.min_height_m + scale * g;
    }
  }
  return h;
}

}  // namespace

HeightmapTerrain::HeightmapTerrain(const HeightmapSpec& spec) : friction_(spec.friction) {
  if (!(spec.max_height_m >= spec.min_height_m)) {
    throw ConfigError(spec.image_file + ": max height must not be below min height");
  }
  h_ = read_image_heights(spec, nx_, ny_);
  init(spec.size_x_m, spec.size_y_m, spec.centre_m);
}

HeightmapTerrain::HeightmapTerrain(int columns, int rows, std::vector<double> heights,
                                   double size_x_m, double size_y_m, double friction,
                                   const Vec2& centre_m)
    : nx_(columns), ny_(rows), friction_(friction), h_(std::move(heights)) {
  if (nx_ < 2 || ny_ < 2) throw ConfigError("height map needs at least 2 x 2 vertices");
  if (h_.size() != static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_)) {
    throw ConfigError("height map: heights.size() must be columns x rows");
  }
  init(size_x_m, size_y_m, centre_m);
}

void HeightmapTerrain::init(double size_x_m, double size_y_m, const Vec2& centre_m) {
  if (!(size_x_m > 0.0) || !(size_y_m > 0.0) || !std::isfinite(size_x_m) ||
      !std::isfinite(size_y_m)) {
    throw ConfigError("height map: sizes must be positive");
  }
  if (!(friction_ > 0.0) || !std::isfinite(friction_)) {
    throw ConfigError("height map: friction must be positive");
  }
  for (double v : h_) {
    if (!std::isfinite(v)) throw ConfigError("height map: heights must be finite");
  }
  dx_ = size_x_m / (nx_ - 1);
  dy_ = size_y_m / (ny_ - 1);
  x_min_ = centre_m.x() - 0.5 * size_x_m;
  y_min_ = centre_m.y() - 0.5 * size_y_m;
  gx_.resize(h_.size());
  gy_.resize(h_.size());
  for (int j = 0; j < ny_; ++j) {
    for (int i = 0; i < nx_; ++i) {
      const int i0 = std::max(i - 1, 0), i1 = std::min(i + 1, nx_ - 1);
      const int j0 = std::max(j - 1, 0), j1 = std::min(j + 1, ny_ - 1);
      gx_[index(i, j)] = (h_[index(i1, j)] - h_[index(i0, j)]) / ((i1 - i0) * dx_);
      gy_[index(i, j)] = (h_[index(i, j1)] - h_[index(i, j0)]) / ((j1 - j0) * dy_);
    }
  }
}

Vec2 HeightmapTerrain::vertex_position(int i, int j) const {
  return Vec2(x_min_ + i * dx_, y_min_ + j * dy_);
}

void HeightmapTerrain::locate(double x, double y, int& i, int& j, double& tx, double& ty) const {
  const double u = clamp((x - x_min_) / dx_, 0.0, nx_ - 1.0);
  const double v = clamp((y - y_min_) / dy_, 0.0, ny_ - 1.0);
  i = std::min(static_cast<int>(u), nx_ - 2);
  j = std::min(static_cast<int>(v), ny_ - 2);
  tx = u - i;
  ty = v - j;
}

double HeightmapTerrain::height(double x, double y) const {
  int i = 0, j = 0;
  double tx = 0.0, ty = 0.0;
  locate(x, y, i, j, tx, ty);
  const double h0 = (1 - tx) * h_[index(i, j)] + tx * h_[index(i + 1, j)];
  const double h1 = (1 - tx) * h_[index(i, j + 1)] + tx * h_[index(i + 1, j + 1)];
  return (1 - ty) * h0 + ty * h1;
}

Vec3 HeightmapTerrain::normal(double x, double y) const {
  int i = 0, j = 0;
  double tx = 0.0, ty = 0.0;
  locate(x, y, i, j, tx, ty);
  auto lerp = [&](const std::vector<double>& g) {
    const double g0 = (1 - tx) * g[index(i, j)] + tx * g[index(i + 1, j)];
    const double g1 = (1 - tx) * g[index(i, j + 1)] + tx * g[index(i + 1, j + 1)];
    return (1 - ty) * g0 + ty * g1;
  };
  // Beyond the border the height is constant across it: no slope in that direction.
  const bool outside_x = x < x_min_ || x > x_min_ + (nx_ - 1) * dx_;
  const bool outside_y = y < y_min_ || y > y_min_ + (ny_ - 1) * dy_;
  const double gx = outside_x ? 0.0 : lerp(gx_);
  const double gy = outside_y ? 0.0 : lerp(gy_);
  return Vec3(-gx, -gy, 1.0).normalized();
}

}  // namespace syndds::terrain
