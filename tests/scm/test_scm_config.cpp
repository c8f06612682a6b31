// Preset files, the strict readers (errors name file:line), and the terrain images.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "scm/scm_images.hpp"
#include "scm_test_util.hpp"

using namespace syndds;
using namespace syndds::scm;
using namespace syndds::scm::test;

namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::filesystem::path temp_dir(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / ("syndds_scm_test_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::string write_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
  return path.string();
}

const char* kSoil =
    "soil:\n"
    "  bekker_kphi: 2.0e6\n"
    "  bekker_kc: 0.0\n"
    "  bekker_n: 1.1\n"
    "  cohesion_pa: 0.0\n"
    "  friction_angle_deg: 30.0\n"
    "  janosi_shear_m: 0.01\n"
    "  elastic_stiffness_pa_per_m: 2.0e8\n"
    "  damping_pa_s_per_m: 3.0e4\n";

}  // namespace

TEST(ScmConfig, PresetFilesHoldTheOracleNumbers) {
  for (const char* name : {"soft", "mid", "hard"}) {
    const SoilPreset p = preset(name);
    const SoilParams code = soil_preset(name);
    EXPECT_EQ(p.soil.bekker_kphi, code.bekker_kphi) << name;
    EXPECT_EQ(p.soil.bekker_kc, code.bekker_kc) << name;
    EXPECT_EQ(p.soil.bekker_n, code.bekker_n) << name;
    EXPECT_EQ(p.soil.cohesion_pa, code.cohesion_pa) << name;
    EXPECT_EQ(p.soil.friction_angle_deg, code.friction_angle_deg) << name;
    EXPECT_EQ(p.soil.janosi_shear_m, code.janosi_shear_m) << name;
    EXPECT_EQ(p.soil.elastic_stiffness_pa_per_m, code.elastic_stiffness_pa_per_m) << name;
    EXPECT_EQ(p.soil.damping_pa_s_per_m, code.damping_pa_s_per_m) << name;
    // SynChrono demo bulldozing settings, off by default.
    EXPECT_FALSE(p.bulldozing.enabled);
    EXPECT_EQ(p.bulldozing.erosion_angle_deg, 55.0);
    EXPECT_EQ(p.bulldozing.flow_factor, 1.0);
    EXPECT_EQ(p.bulldozing.iterations, 5);
    EXPECT_EQ(p.bulldozing.propagations, 10);
  }
  EXPECT_EQ(preset("hard").soil.bekker_kphi, 5301e3);
  EXPECT_EQ(preset("soft").soil.bekker_kphi, 0.2e6);
  EXPECT_THROW(soil_preset("mud"), ConfigError);
}

TEST(ScmConfig, UnknownKeyNamesFileAndLine) {
  const auto dir = temp_dir("unknown");
  const std::string file = write_file(dir / "bad.yaml", std::string(kSoil) + "  bekker_kphii: 3\n");
  const std::string err = error_of([&] { load_soil_preset_file(file); });
  EXPECT_NE(err.find(file + ":10:3"), std::string::npos) << err;
  EXPECT_NE(err.find("unknown key 'bekker_kphii'"), std::string::npos) << err;
}

TEST(ScmConfig, BadValuesNameFileLineAndKey) {
  const auto dir = temp_dir("values");
  std::string text = kSoil;
  text.replace(text.find("bekker_n: 1.1"), 13, "bekker_n: -1");
  const std::string file = write_file(dir / "n.yaml", text);
  std::string err = error_of([&] { load_soil_preset_file(file); });
  EXPECT_NE(err.find(file + ":4:13: soil.bekker_n: must be in"), std::string::npos) << err;

  const std::string missing = write_file(dir / "missing.yaml", "soil:\n  bekker_kphi: 1e6\n");
  err = error_of([&] { load_soil_preset_file(missing); });
  EXPECT_NE(err.find(missing + ":2:3: soil: missing required key"), std::string::npos) << err;

  const std::string iters = write_file(
      dir / "iters.yaml", std::string(kSoil) + "bulldozing:\n  enabled: true\n  iterations: 2.5\n");
  err = error_of([&] { load_soil_preset_file(iters); });
  EXPECT_NE(err.find(iters + ":12:15: bulldozing.iterations: expected an integer"),
            std::string::npos)
      << err;
}

TEST(ScmConfig, ScenarioBlockReadsPresetAreaAndOverrides) {
  const std::string terrain_dir = std::string(SYNDDS_TEST_CONFIG_DIR) + "/terrain";
  auto root = YamlNode::load_string(
      "terrain:\n"
      "  type: scm\n"
      "  preset: soft\n"
      "  spacing_m: 0.05\n"
      "  area: {x_min_m: -10, x_max_m: 40, y_min_m: -5, y_max_m: 5}\n"
      "  threads: 2\n"
      "  bulldozing: {enabled: true, iterations: 3}\n",
      "scenario.yaml");
  MapReader top(root);
  const ScmParams p = parse_scm_params(top.required("terrain"), terrain_dir);
  top.finish();
  EXPECT_EQ(p.soil.bekker_kphi, 0.2e6);
  EXPECT_EQ(p.grid.spacing_m, 0.05);
  EXPECT_EQ(p.grid.x_max_m, 40.0);
  EXPECT_EQ(p.threads, 2);
  EXPECT_TRUE(p.bulldozing.enabled);
  EXPECT_EQ(p.bulldozing.iterations, 3);
  EXPECT_EQ(p.bulldozing.propagations, 10);  // from the preset file

  auto bad = YamlNode::load_string(
      "terrain:\n"
      "  preset: mid\n"
      "  spacing_m: 0.05\n"
      "  area: {x_min_m: 10, x_max_m: 0, y_min_m: -5, y_max_m: 5}\n",
      "bad.yaml");
  MapReader b(bad);
  std::string err = error_of([&] { parse_scm_params(b.required("terrain"), terrain_dir); });
  EXPECT_NE(err.find("bad.yaml:4:9"), std::string::npos) << err;

  auto both = YamlNode::load_string(
      std::string("terrain:\n  preset: mid\n  spacing_m: 0.05\n") +
          "  area: {x_min_m: 0, x_max_m: 1, y_min_m: 0, y_max_m: 1}\n  sol: 1\n",
      "typo.yaml");
  MapReader t(both);
  err = error_of([&] { parse_scm_params(t.required("terrain"), terrain_dir); });
  EXPECT_NE(err.find("typo.yaml:5:3"), std::string::npos) << err;
  EXPECT_NE(err.find("unknown key 'sol'"), std::string::npos) << err;

  auto unknown_preset = YamlNode::load_string(
      "terrain: {preset: mud, spacing_m: 0.05, area: {x_min_m: 0, x_max_m: 1, y_min_m: 0, "
      "y_max_m: 1}}\n",
      "p.yaml");
  MapReader u(unknown_preset);
  err = error_of([&] { parse_scm_params(u.required("terrain"), terrain_dir); });
  EXPECT_NE(err.find("p.yaml:1:19: terrain.preset: must be one of"), std::string::npos) << err;
}

TEST(ScmConfig, InvalidParamsInCodeAreRejected) {
  ScmParams p = params("mid", 0.05);
  p.grid.spacing_m = 0.0;
  EXPECT_THROW(ScmTerrain{p}, ConfigError);
  p = params("mid", 0.05);
  p.soil.janosi_shear_m = 0.0;
  EXPECT_THROW(ScmTerrain{p}, ConfigError);
}

namespace {
// A wheel sunk 4 cm rolled 1 m along +x from the origin on mid soil at 0.05 m.
void roll_a_rut(ScmTerrain& t) {
  terrain::WheelBodyState w;
  w.pose.position = Vec3(0.0, 0.0, 0.467 - 0.04);
  w.linear_velocity = Vec3(1.0, 0.0, 0.0);
  w.angular_velocity = Vec3(0.0, 1.0 / 0.467, 0.0);
  w.radius_m = 0.467;
  w.width_m = 0.254;
  terrain::WheelLoad l;
  for (int k = 0; k < 500; ++k) {
    t.compute_wheel_loads(std::span(&w, 1), 2e-3, std::span(&l, 1));
    w.pose.position += 2e-3 * w.linear_velocity;
  }
}
}  // namespace

TEST(ScmImages, HeightAndRutImagesMapBackToMetres) {
  ScmParams p = params("mid", 0.05, 3.0);
  ScmTerrain t(p);
  roll_a_rut(t);
  const auto dir = temp_dir("images");
  const TerrainImageInfo info = write_terrain_images(t, (dir / "final").string());
  const cv::Mat h = cv::imread(info.height_png, cv::IMREAD_UNCHANGED);
  const cv::Mat r = cv::imread(info.rut_png, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(h.type(), CV_16UC1);
  ASSERT_EQ(r.type(), CV_16UC1);
  EXPECT_EQ(h.cols, info.width_px);
  EXPECT_EQ(h.rows, info.height_px);
  EXPECT_NEAR(info.rut_depth_max_m, 0.04, 1e-4);
  // Vertex (10, 0) sits in the rut: read it back through the documented mapping.
  const int col = 10 - info.region.i_min, row = info.region.j_max - 0;
  const double height = info.height_min_m + h.at<std::uint16_t>(row, col) * info.height_m_per_count;
  const double depth = r.at<std::uint16_t>(row, col) * info.rut_depth_m_per_count;
  EXPECT_NEAR(height, t.vertex_height(10, 0), info.height_m_per_count);
  EXPECT_NEAR(depth, -t.vertex_height(10, 0), info.rut_depth_m_per_count);
  EXPECT_GT(depth, 0.03);
  // The side file carries the same scale.
  std::ifstream in(info.json);
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["width_px"].get<int>(), info.width_px);
  EXPECT_DOUBLE_EQ(j["height_m_per_count"].get<double>(), info.height_m_per_count);
  EXPECT_DOUBLE_EQ(j["x_of_column0_m"].get<double>(), info.region.i_min * 0.05);
}

// The picture for people beside the data images: the rut depth through the viridis colour map
// (each vertex a square of colour_scale_px pixels), axes, a scale bar and a colour bar.
TEST(ScmImages, RutColourPictureHasMapAxesScaleAndColourBar) {
  ScmParams p = params("mid", 0.05, 3.0);
  ScmTerrain t(p);
  roll_a_rut(t);
  const auto dir = temp_dir("colour");
  const TerrainImageInfo info = write_terrain_images(t, (dir / "terrain").string());
  EXPECT_EQ(info.rut_colour_png, (dir / "terrain_rut_colour.png").string());
  const cv::Mat img = cv::imread(info.rut_colour_png, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(img.type(), CV_8UC3);
  EXPECT_EQ(img.cols, info.colour_width_px);
  EXPECT_EQ(img.rows, info.colour_height_px);
  // The map is at least about 600 px on its long side, in whole pixels per vertex.
  const int k = info.colour_scale_px;
  EXPECT_EQ(k, std::max(1, 600 / std::max(info.width_px, info.height_px)));
  const cv::Rect map(info.map_left_px, info.map_top_px, info.width_px * k, info.height_px * k);
  const cv::Rect bar(info.bar_left_px, info.bar_top_px, info.bar_width_px, info.bar_height_px);
  const cv::Rect whole(0, 0, img.cols, img.rows);
  ASSERT_EQ(map & whole, map);
  ASSERT_EQ(bar & whole, bar);
  EXPECT_GE(map.x, 40);                    // room for the y axis labels
  EXPECT_GE(img.rows - map.br().y, 60);    // x axis labels and the scale bar below
  EXPECT_GT(bar.x, map.br().x);            // the colour bar right of the map
  EXPECT_GE(img.cols - bar.br().x, 50);    // its labels right of it

  auto viridis = [](double depth, double dmax) {
    cv::Mat1b v(1, 1, static_cast<std::uint8_t>(std::lround(255.0 * depth / dmax)));
    cv::Mat c;
    cv::applyColorMap(v, c, cv::COLORMAP_VIRIDIS);
    return c.at<cv::Vec3b>(0, 0);
  };
  // Vertex (10, 0) in the rut: its square has the colour of its depth; the whole square.
  const double depth = -t.vertex_height(10, 0);
  ASSERT_GT(depth, 0.03);
  const int col = 10 - info.region.i_min, row = info.region.j_max - 0;
  for (int dy = 0; dy < k; ++dy) {
    for (int dx = 0; dx < k; ++dx) {
      ASSERT_EQ(img.at<cv::Vec3b>(map.y + row * k + dy, map.x + col * k + dx),
                viridis(depth, info.rut_depth_max_m));
    }
  }
  // Undisturbed soil (a corner of the region) is the colour of depth 0.
  EXPECT_EQ(img.at<cv::Vec3b>(map.y, map.x), viridis(0.0, 1.0));
  // The colour bar runs from depth 0 at the bottom to the deepest rut at the top.
  EXPECT_EQ(img.at<cv::Vec3b>(bar.br().y - 1, bar.x + bar.width / 2), viridis(0.0, 1.0));
  EXPECT_EQ(img.at<cv::Vec3b>(bar.y, bar.x + bar.width / 2), viridis(1.0, 1.0));
  // Ink (text, ticks, the scale bar) in each margin: axes and labels were drawn.
  auto ink = [&](const cv::Rect& r) {
    int n = 0;
    for (int y = r.y; y < r.br().y; ++y) {
      for (int x = r.x; x < r.br().x; ++x) {
        const auto& px = img.at<cv::Vec3b>(y, x);
        n += px[0] < 100 && px[1] < 100 && px[2] < 100;
      }
    }
    return n;
  };
  EXPECT_GT(ink(cv::Rect(0, map.y, map.x - 2, map.height)), 20) << "y axis labels";
  EXPECT_GT(ink(cv::Rect(map.x, map.br().y + 2, map.width, 45)), 40) << "x axis labels";
  EXPECT_GT(ink(cv::Rect(map.x, img.rows - 30, map.width, 28)), 40) << "scale bar";
  EXPECT_GT(ink(cv::Rect(bar.br().x + 2, bar.y - 6, img.cols - bar.br().x - 2, bar.height + 12)),
            40)
      << "colour bar labels";
  // The data images are unchanged by it, and the side file names the picture.
  std::ifstream in(info.json);
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["rut_colour_png"].get<std::string>(), "terrain_rut_colour.png");
  // Deterministic: the same terrain gives the same bytes.
  const TerrainImageInfo again = write_terrain_images(t, (dir / "again").string());
  auto bytes = [](const std::string& f) {
    std::ifstream s(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(s), {});
  };
  EXPECT_EQ(bytes(again.rut_colour_png), bytes(info.rut_colour_png));
}
