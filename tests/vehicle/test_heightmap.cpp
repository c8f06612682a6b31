// Height-map terrain: images generated at run time (8 and 16-bit grey PNG), heights and
// normals at known points.
#include <gtest/gtest.h>

#include <filesystem>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/error.hpp"
#include "terrain/heightmap_terrain.hpp"

using namespace syndds;
using namespace syndds::terrain;

namespace {
std::string temp_file(const std::string& name) { return ::testing::TempDir() + "/" + name; }
}  // namespace

// A plane h = 2 + 0.05 (x - x_min) + 0.02 (y - y_min) written to a 16-bit image: heights are
// exact to the quantisation step everywhere (bilinear is exact on a plane), normals exact.
TEST(HeightmapTerrain, SixteenBitPlaneGivesHeightsAndNormals) {
  const int w = 65, h = 33;
  const double sx = 64.0, sy = 32.0, lo = 2.0, hi = 2.0 + 0.05 * sx + 0.02 * sy;
  cv::Mat img(h, w, CV_16U);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const double x = c * sx / (w - 1), y = (h - 1 - r) * sy / (h - 1);  // row 0 = north
      const double z = 2.0 + 0.05 * x + 0.02 * y;
      img.at<std::uint16_t>(r, c) =
          static_cast<std::uint16_t>(std::lround((z - lo) / (hi - lo) * 65535.0));
    }
  }
  const std::string file = temp_file("plane16.png");
  ASSERT_TRUE(cv::imwrite(file, img));
  HeightmapSpec spec;
  spec.image_file = file;
  spec.size_x_m = sx;
  spec.size_y_m = sy;
  spec.min_height_m = lo;
  spec.max_height_m = hi;
  spec.friction = 0.6;
  spec.centre_m = Vec2(10.0, -5.0);
  const HeightmapTerrain t(spec);
  EXPECT_EQ(t.columns(), w);
  EXPECT_EQ(t.rows(), h);
  const double x_min = 10.0 - sx / 2, y_min = -5.0 - sy / 2;
  const double quantum = (hi - lo) / 65535.0;
  for (double fx : {0.0, 0.13, 0.5, 0.77, 1.0}) {
    for (double fy : {0.0, 0.31, 0.5, 1.0}) {
      const double x = x_min + fx * sx, y = y_min + fy * sy;
      EXPECT_NEAR(t.height(x, y), 2.0 + 0.05 * fx * sx + 0.02 * fy * sy, quantum);
      const Vec3 n = t.normal(x, y);
      const Vec3 expected = Vec3(-0.05, -0.02, 1.0).normalized();
      EXPECT_LT((n - expected).norm(), 1e-4) << n.transpose();
    }
  }
  EXPECT_DOUBLE_EQ(t.friction(0, 0), 0.6);
  // Outside the map the border continues: constant across the border, slope along it.
  EXPECT_NEAR(t.height(x_min - 50, y_min), 2.0, quantum);
  EXPECT_NEAR(t.height(x_min - 50, y_min + 10), 2.0 + 0.02 * 10, quantum);
  EXPECT_LT((t.normal(x_min - 50, y_min + 10) - Vec3(0, -0.02, 1).normalized()).norm(), 1e-4);
}

// An 8-bit image with one bump: vertex heights, bilinear between vertices, orientation
// (row 0 north, column 0 west) and the normal on the bump's flanks.
TEST(HeightmapTerrain, EightBitBumpHeightsAndNormals) {
  cv::Mat img(5, 5, CV_8U, cv::Scalar(0));
  img.at<std::uint8_t>(1, 3) = 255;  // row 1 from the north, column 3 from the west
  const std::string file = temp_file("bump8.png");
  ASSERT_TRUE(cv::imwrite(file, img));
  HeightmapSpec spec;
  spec.image_file = file;
  spec.size_x_m = 8.0;  // spacing 2 m
  spec.size_y_m = 8.0;
  spec.min_height_m = -1.0;
  spec.max_height_m = 3.0;
  const HeightmapTerrain t(spec);
  // Vertex (i 3, j 3) (j counted from the south) is at x = -4 + 6, y = -4 + 6.
  EXPECT_DOUBLE_EQ(t.height(2.0, 2.0), 3.0);
  EXPECT_DOUBLE_EQ(t.height(0.0, 2.0), -1.0);
  EXPECT_DOUBLE_EQ(t.height(1.0, 2.0), 1.0);   // halfway along x
  EXPECT_DOUBLE_EQ(t.height(1.0, 1.0), 0.0);   // cell centre: mean of 3, -1, -1, -1
  EXPECT_DOUBLE_EQ(t.height(2.0, -2.0), -1.0);
  // Central differences at the neighbour vertex west of the bump: dh/dx = 4 / 4 m.
  const Vec3 n = t.normal(0.0, 2.0);
  EXPECT_LT((n - Vec3(-1.0, 0.0, 1.0).normalized()).norm(), 1e-12);
  // On top of the bump the gradient is zero.
  EXPECT_LT((t.normal(2.0, 2.0) - Vec3::UnitZ()).norm(), 1e-12);
}

TEST(HeightmapTerrain, BadInputIsAClearError) {
  HeightmapSpec spec;
  spec.image_file = temp_file("does_not_exist.png");
  spec.size_x_m = spec.size_y_m = 10.0;
  spec.max_height_m = 1.0;
  try {
    HeightmapTerrain t(spec);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("does_not_exist.png: cannot read"), std::string::npos);
  }
  EXPECT_THROW(HeightmapTerrain(1, 3, std::vector<double>(3, 0.0), 10, 10), ConfigError);
  EXPECT_THROW(HeightmapTerrain(2, 2, std::vector<double>(3, 0.0), 10, 10), ConfigError);
  EXPECT_THROW(HeightmapTerrain(2, 2, std::vector<double>(4, 0.0), -1, 10), ConfigError);
}

TEST(HeightmapTerrain, SpecFromYaml) {
  cv::Mat img(3, 3, CV_8U, cv::Scalar(128));
  const std::string dir = ::testing::TempDir();
  ASSERT_TRUE(cv::imwrite(dir + "/flat8.png", img));
  const auto node = YamlNode::load_string(
      "image: flat8.png\nsize_m: [20, 10]\nheight_range_m: [0, 2]\nfriction: 0.5\n", "t.yaml");
  const auto spec = parse_heightmap_spec(node, dir);
  EXPECT_TRUE(std::filesystem::equivalent(spec.image_file, dir + "/flat8.png"));
  EXPECT_DOUBLE_EQ(spec.size_x_m, 20.0);
  EXPECT_DOUBLE_EQ(spec.max_height_m, 2.0);
  const HeightmapTerrain t(spec);
  EXPECT_NEAR(t.height(3, 3), 2.0 * 128 / 255, 1e-12);
  const auto bad = YamlNode::load_string(
      "image: flat8.png\nsize_m: [20, 10]\nheight_range_m: [0, 2]\nfricton: 0.5\n", "t.yaml");
  EXPECT_THROW(parse_heightmap_spec(bad, dir), ConfigError);
  const auto missing = YamlNode::load_string(
      "image: nope.png\nsize_m: [20, 10]\nheight_range_m: [0, 2]\n", "t.yaml");
  EXPECT_THROW(parse_heightmap_spec(missing, dir), ConfigError);
}
