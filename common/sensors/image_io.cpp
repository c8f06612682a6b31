#include "sensors/image_io.hpp"

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
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

namespace {

const std::string& checked_video_path(const std::string& path, const VideoWriter::Options& o) {
  if (std::filesystem::path(path).extension() != ".avi") {
    throw std::invalid_argument(path + ": a video is written as MJPG in AVI: the name must end "
                                "in .avi");
  }
  if (o.jpeg_quality < 1 || o.jpeg_quality > 100) {
    throw std::invalid_argument(path + ": jpeg_quality " + std::to_string(o.jpeg_quality) +
                                " is outside 1..100");
  }
  return path;
}

}  // namespace

VideoWriter::VideoWriter(const std::string& path, double fps, int width, int height, Open open,
                         Options options)
    : path_(checked_video_path(path, options)),
      quality_(options.jpeg_quality),
      file_(path, AviFile::Format{width, height, fps, options.segment_bytes}, open) {}

VideoWriter::~VideoWriter() = default;

void VideoWriter::write(const RgbImage& image) {
  if (image.width != file_.format().width || image.height != file_.format().height ||
      image.pixels.size() != static_cast<std::size_t>(image.width) * image.height * 3) {
    throw std::runtime_error("video frame size differs from " + path_);
  }
  std::vector<std::uint8_t> jpeg;
  if (!cv::imencode(".jpg", to_bgr(image), jpeg, {cv::IMWRITE_JPEG_QUALITY, quality_})) {
    throw std::runtime_error(path_ + ": cannot encode a frame as JPEG");
  }
  file_.append(jpeg);
}

void VideoWriter::close() { file_.close(); }

void VideoWriter::save_state(core::StateWriter& w) const {
  w.begin("video_writer", 1);
  w.io(quality_);
  file_.save_state(w);
  w.end();
}

void VideoWriter::load_state(core::StateReader& r) {
  r.begin("video_writer", 1, 1);
  const auto quality = r.get<int>();
  if (quality != quality_) {
    r.fail(path_ + ": the checkpoint's video has JPEG quality " + std::to_string(quality) +
           ", this one " + std::to_string(quality_));
  }
  file_.load_state(r);
  r.end();
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
