#include "sensors/image_io.hpp"

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <stdexcept>

namespace syndds::sensors {
namespace {

cv::Mat to_bgr(const RgbImage& image) {
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.pixels.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  return bgr;
}

void make_parent(const std::string& path) {
  const auto parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent);
}

}  // namespace

void write_png(const std::string& path, const RgbImage& image) {
  if (image.pixels.size() != static_cast<std::size_t>(image.width) * image.height * 3) {
    throw std::runtime_error("write_png: malformed image for " + path);
  }
  make_parent(path);
  if (!cv::imwrite(path, to_bgr(image))) throw std::runtime_error("cannot write " + path);
}

RgbImage read_image(const std::string& path) {
  const cv::Mat bgr = cv::imread(path, cv::IMREAD_COLOR);
  if (bgr.empty()) throw std::runtime_error("cannot read image " + path);
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  RgbImage out;
  out.width = rgb.cols;
  out.height = rgb.rows;
  out.pixels.assign(rgb.data, rgb.data + rgb.total() * 3);
  return out;
}

VideoWriter::VideoWriter(const std::string& path, double fps, int width, int height)
    : writer_(std::make_unique<cv::VideoWriter>()), path_(path), width_(width), height_(height) {
  make_parent(path);
  const std::string ext = std::filesystem::path(path).extension().string();
  const int fourcc = ext == ".mp4" ? cv::VideoWriter::fourcc('m', 'p', '4', 'v')
                                   : cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
  if (!writer_->open(path, fourcc, fps, cv::Size(width, height), true)) {
    path_ = std::filesystem::path(path).replace_extension(".avi").string();
    if (!writer_->open(path_, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps,
                       cv::Size(width, height), true)) {
      throw std::runtime_error("cannot open a video writer for " + path);
    }
  }
}

VideoWriter::~VideoWriter() { close(); }

void VideoWriter::write(const RgbImage& image) {
  if (image.width != width_ || image.height != height_) {
    throw std::runtime_error("video frame size differs from " + path_);
  }
  writer_->write(to_bgr(image));
  ++frames_;
}

void VideoWriter::close() {
  if (writer_ && writer_->isOpened()) writer_->release();
}

void write_ply(const std::string& path, const LidarScan& scan) {
  make_parent(path);
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << "ply\nformat ascii 1.0\ncomment sensor " << scan.sensor_id << " time " << scan.stamp.time_s
      << "\nelement vertex " << scan.points.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\n"
         "property float range\nproperty ushort channel\nproperty ushort sample\nend_header\n";
  for (const auto& p : scan.points) {
    out << p.x << ' ' << p.y << ' ' << p.z << ' ' << p.intensity << ' ' << p.range << ' '
        << p.channel << ' ' << p.sample << '\n';
  }
  if (!out) throw std::runtime_error("error writing " + path);
}

}  // namespace syndds::sensors
