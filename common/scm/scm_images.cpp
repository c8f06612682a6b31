#include "scm/scm_images.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
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

// A "nice" tick step (1, 2 or 5 times a power of ten) giving about `ticks` steps over `range`.
double nice_step(double range, int ticks) {
  const double raw = std::max(range, 1e-12) / ticks;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double norm = raw / mag;
  return (norm < 1.5 ? 1.0 : norm < 3.0 ? 2.0 : norm < 7.0 ? 5.0 : 10.0) * mag;
}

// A number for a label: %g of the value rounded to the step (no -0, no 0.30000000000000004).
std::string label(double value, double step) {
  const double v = std::round(value / step) * step;
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", std::abs(v) < 1e-12 ? 0.0 : v);
  return buf;
}

const cv::Scalar kInk(0, 0, 0);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kFontScale = 0.45;

void text(cv::Mat& img, const std::string& s, cv::Point at, bool centred = false,
          bool right = false) {
  int base = 0;
  const cv::Size size = cv::getTextSize(s, kFont, kFontScale, 1, &base);
  if (centred) at.x -= size.width / 2;
  if (right) at.x -= size.width;
  cv::putText(img, s, at, kFont, kFontScale, kInk, 1, cv::LINE_AA);
}

// The rut depth picture (see scm_images.hpp): map, axes, scale bar, colour bar.
void draw_rut_colour(const cv::Mat1d& ruts, double dmax, const ImageRegion& r, double spacing,
                     TerrainImageInfo& info, cv::Mat& out) {
  const int w = ruts.cols, h = ruts.rows;
  // Whole pixels per vertex: the map at least about 600 px on its long side.
  const int k = std::max(1, 600 / std::max(w, h));
  const int map_w = w * k, map_h = h * k;
  constexpr int kLeft = 70, kTop = 34, kBottom = 86, kGap = 24, kBarWidth = 22, kRight = 90;
  const int bar_h = std::max(map_h, 120);
  info.colour_scale_px = k;
  info.map_left_px = kLeft;
  info.map_top_px = kTop;
  info.bar_left_px = kLeft + map_w + kGap;
  info.bar_top_px = kTop;
  info.bar_width_px = kBarWidth;
  info.bar_height_px = bar_h;
  info.colour_width_px = info.bar_left_px + kBarWidth + kRight;
  info.colour_height_px = kTop + std::max(map_h, bar_h) + kBottom;
  out = cv::Mat(info.colour_height_px, info.colour_width_px, CV_8UC3, cv::Scalar(255, 255, 255));

  // The map: depth 0..dmax -> 0..255 -> viridis.
  cv::Mat1b grey(h, w);
  for (int row = 0; row < h; ++row) {
    for (int col = 0; col < w; ++col) {
      grey(row, col) = static_cast<std::uint8_t>(
          dmax > 0.0 ? std::clamp(std::lround(255.0 * ruts(row, col) / dmax), 0L, 255L) : 0);
    }
  }
  cv::Mat coloured, big;
  cv::applyColorMap(grey, coloured, cv::COLORMAP_VIRIDIS);
  cv::resize(coloured, big, cv::Size(map_w, map_h), 0, 0, cv::INTER_NEAREST);
  big.copyTo(out(cv::Rect(kLeft, kTop, map_w, map_h)));
  cv::rectangle(out, cv::Rect(kLeft - 1, kTop - 1, map_w + 2, map_h + 2), kInk, 1);

  // Axes in metres: vertex i at x = i s (pixel centre of its square), north up.
  const double x0 = r.i_min * spacing, x1 = r.i_max * spacing;
  const double y0 = r.j_min * spacing, y1 = r.j_max * spacing;
  auto px_of_x = [&](double x) { return kLeft + (x / spacing - r.i_min + 0.5) * k; };
  auto py_of_y = [&](double y) { return kTop + (r.j_max - y / spacing + 0.5) * k; };
  const double sx = nice_step(std::max(x1 - x0, spacing), std::max(2, map_w / 90));
  for (double x = std::ceil(x0 / sx - 1e-9) * sx; x <= x1 + 1e-9 * sx; x += sx) {
    const int px = static_cast<int>(std::lround(px_of_x(x)));
    cv::line(out, {px, kTop + map_h}, {px, kTop + map_h + 5}, kInk, 1);
    text(out, label(x, sx), {px, kTop + map_h + 20}, true);
  }
  text(out, "x (m, east)", {kLeft + map_w / 2, kTop + map_h + 40}, true);
  const double sy = nice_step(std::max(y1 - y0, spacing), std::max(2, map_h / 60));
  for (double y = std::ceil(y0 / sy - 1e-9) * sy; y <= y1 + 1e-9 * sy; y += sy) {
    const int py = static_cast<int>(std::lround(py_of_y(y)));
    cv::line(out, {kLeft - 6, py}, {kLeft - 1, py}, kInk, 1);
    text(out, label(y, sy), {kLeft - 9, py + 5}, false, true);
  }
  text(out, "y (m)", {4, kTop - 12});
  text(out, "rut depth, north up", {kLeft + map_w / 2, kTop - 12}, true);

  // Scale bar: a nice length of at most about a third of the map's width.
  const double third = std::max((x1 - x0 + spacing) / 3.0, spacing);
  double bar_m = nice_step(third, 1);
  if (bar_m > third) bar_m /= 2.0;
  const int bar_px = std::max(1, static_cast<int>(std::lround(bar_m / spacing * k)));
  const int sy0 = kTop + std::max(map_h, bar_h) + 62;
  cv::rectangle(out, cv::Rect(kLeft, sy0, bar_px, 6), kInk, cv::FILLED);
  cv::line(out, {kLeft, sy0 - 4}, {kLeft, sy0 + 9}, kInk, 1);
  cv::line(out, {kLeft + bar_px - 1, sy0 - 4}, {kLeft + bar_px - 1, sy0 + 9}, kInk, 1);
  text(out, label(bar_m, bar_m / 100.0) + " m", {kLeft + bar_px + 8, sy0 + 8});

  // Colour bar: depth 0 at the bottom, the deepest rut at the top, labelled in metres.
  cv::Mat1b ramp(bar_h, 1);
  for (int row = 0; row < bar_h; ++row) {
    ramp(row, 0) = static_cast<std::uint8_t>(
        std::lround(255.0 * (bar_h - 1 - row) / std::max(1, bar_h - 1)));
  }
  cv::Mat ramp_colour, ramp_wide;
  cv::applyColorMap(ramp, ramp_colour, cv::COLORMAP_VIRIDIS);
  cv::resize(ramp_colour, ramp_wide, cv::Size(kBarWidth, bar_h), 0, 0, cv::INTER_NEAREST);
  ramp_wide.copyTo(out(cv::Rect(info.bar_left_px, kTop, kBarWidth, bar_h)));
  cv::rectangle(out, cv::Rect(info.bar_left_px - 1, kTop - 1, kBarWidth + 2, bar_h + 2), kInk, 1);
  const double top_m = dmax > 0.0 ? dmax : 1.0;
  const double sd = nice_step(top_m, 5);
  for (double d = 0.0; d <= top_m * (1.0 + 1e-9); d += sd) {
    const int py = kTop + static_cast<int>(std::lround((bar_h - 1) * (1.0 - d / top_m)));
    const int bx = info.bar_left_px + kBarWidth;
    cv::line(out, {bx, py}, {bx + 5, py}, kInk, 1);
    text(out, label(d, sd), {bx + 8, py + 5});
  }
  text(out, "depth (m)", {info.bar_left_px - 6, kTop - 12});
  if (!(dmax > 0.0)) text(out, "no rut", {info.bar_left_px - 6, kTop + bar_h + 20});
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
  info.rut_colour_png = prefix + "_rut_colour.png";
  cv::Mat colour;
  draw_rut_colour(ruts, dmax, r, terrain.spacing(), info, colour);
  write_png(info.rut_colour_png, colour);
  nlohmann::json j;
  // The images sit beside this file: names, not paths, so that the run directory can move and
  // the file is the same wherever the run was written.
  j["height_png"] = std::filesystem::path(info.height_png).filename().string();
  j["rut_png"] = std::filesystem::path(info.rut_png).filename().string();
  j["rut_colour_png"] = std::filesystem::path(info.rut_colour_png).filename().string();
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
