#pragma once
// Writing sensor output: PNG frames and MJPG AVI videos (OpenCV's JPEG codec), point clouds as
// ASCII PLY.
#include <cstdint>
#include <string>

#include "core/state_io.hpp"
#include "sensors/avi_file.hpp"
#include "sensors/camera.hpp"
#include "sensors/lidar.hpp"

namespace syndds::sensors {

/// Writes an RGB image as PNG (creates parent directories). Throws std::runtime_error on failure.
void write_png(const std::string& path, const RgbImage& image);
/// Reads a PNG/JPEG into an RGB image. Throws std::runtime_error on failure.
RgbImage read_image(const std::string& path);

struct VideoOptions {
  int jpeg_quality = 90;  // 1..100, the same for every frame
  std::uint64_t segment_bytes = AviFile::kDefaultSegmentBytes;
};

/// A video file of fixed size and frame rate: MJPG in an AVI file (sensors::AviFile), every
/// frame a JPEG (OpenCV's encoder, libjpeg) of a fixed quality. The bytes of the file follow
/// from the frames written (the JPEG encoder is deterministic), and a checkpoint can cut the
/// file back and continue it: save_state() / load_state().
class VideoWriter {
 public:
  using Options = VideoOptions;
  using Open = AviFile::Open;
  /// `path` must end in .avi. With Open::resume the file of a checkpointed run is reopened as it
  /// is, and load_state() must come before write() or close(). Throws std::invalid_argument
  /// (naming the file and the field) for a bad format, std::runtime_error if it cannot open it.
  VideoWriter(const std::string& path, double fps, int width, int height, Open open = Open::create,
              Options options = {});
  ~VideoWriter();
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;
  /// Appends a frame (must match the size given at construction).
  void write(const RgbImage& image);
  const std::string& path() const { return path_; }
  int frames() const { return static_cast<int>(file_.frames()); }
  /// Finishes the file: the index, the header's sizes and counts. Once; the destructor does it
  /// too, without reporting errors.
  void close();
  /// Closes and removes the file.
  void discard() { file_.discard(); }
  /// Checkpoints: the JPEG quality and the file's frames (AviFile::save_state).
  void save_state(core::StateWriter& w) const;
  /// Cuts the file back to the frames of the state (AviFile::load_state).
  void load_state(core::StateReader& r);

 private:
  std::string path_;
  int quality_;
  AviFile file_;
};

/// Writes a scan as ASCII PLY (x y z intensity range channel sample), sensor frame.
void write_ply(const std::string& path, const LidarScan& scan);

}  // namespace syndds::sensors
