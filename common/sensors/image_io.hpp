#pragma once
// Writing sensor output: PNG frames and video files (OpenCV), point clouds as ASCII PLY.
#include <memory>
#include <string>

#include "sensors/camera.hpp"
#include "sensors/lidar.hpp"

namespace cv {
class VideoWriter;
}

namespace syndds::sensors {

/// Writes an RGB image as PNG (creates parent directories). Throws std::runtime_error on failure.
void write_png(const std::string& path, const RgbImage& image);
/// Reads a PNG/JPEG into an RGB image. Throws std::runtime_error on failure.
RgbImage read_image(const std::string& path);

/// A video file of fixed size and frame rate. Tries the codec the file extension suggests
/// (.avi: MJPG, .mp4: mp4v), then MJPG in an .avi beside it if that fails.
class VideoWriter {
 public:
  VideoWriter(const std::string& path, double fps, int width, int height);
  ~VideoWriter();
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;
  /// Appends a frame (must match the size given at construction).
  void write(const RgbImage& image);
  /// The file actually written (may differ from the request after a codec fallback).
  const std::string& path() const { return path_; }
  int frames() const { return frames_; }
  void close();

 private:
  std::unique_ptr<cv::VideoWriter> writer_;
  std::string path_;
  int width_, height_;
  int frames_ = 0;
};

/// Writes a scan as ASCII PLY (x y z intensity range channel sample), sensor frame.
void write_ply(const std::string& path, const LidarScan& scan);

}  // namespace syndds::sensors
