// Camera videos (sensors::VideoWriter over sensors::AviFile): the file plays with OpenCV's
// reader, its bytes follow from the frames alone, and a checkpoint cuts it back and continues
// it, in the same object (a rollback) or in a new one on the same file (a restarted process),
// so that it ends byte-identical to a file written straight through; also across OpenDML
// segments and after the file was finished. A file never finished (a killed process) plays up
// to its last whole frame.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/videoio.hpp>
#include <sstream>

#include "../core/state_test_util.hpp"
#include "sensors/image_io.hpp"

using namespace syndds;
using namespace syndds::sensors;
namespace fs = std::filesystem;

namespace {

constexpr int kWidth = 64;
constexpr int kHeight = 48;
constexpr double kFps = 15.0;

/// A fresh folder, removed at the end of a test that passed.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() /
             ("syndds_video_" + name + "_" + std::to_string(getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    if (!testing::Test::HasFailure()) fs::remove_all(path, ec);
  }
  fs::path operator/(const std::string& name) const { return path / name; }
};

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Frame k: a gradient, a square that moves and noise from a fixed generator, so that the
/// JPEG sizes differ from frame to frame (odd ones among them).
RgbImage frame(int k) {
  RgbImage img;
  img.width = kWidth;
  img.height = kHeight;
  std::uint32_t state = 2166136261u ^ static_cast<std::uint32_t>(k);
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      state = state * 1664525u + 1013904223u;
      const int noise = static_cast<int>(state >> 28);
      const bool square = std::abs(u - (k * 3) % kWidth) < 8 && std::abs(v - 20) < 8;
      img.pixels.push_back(static_cast<std::uint8_t>(square ? 230 : 4 * u + noise));
      img.pixels.push_back(static_cast<std::uint8_t>(square ? 30 : 5 * v + noise));
      img.pixels.push_back(static_cast<std::uint8_t>((40 + 7 * k + noise) % 256));
    }
  }
  return img;
}

VideoWriter::Options segments_of(std::uint64_t bytes) {
  VideoWriter::Options o;
  o.segment_bytes = bytes;
  return o;
}

/// Frames [0, n) written straight through and closed; the file's bytes.
std::string straight(const fs::path& file, int n, VideoWriter::Options options = {}) {
  VideoWriter video(file.string(), kFps, kWidth, kHeight, VideoWriter::Open::create, options);
  for (int k = 0; k < n; ++k) video.write(frame(k));
  video.close();
  return bytes_of(file);
}

std::string state_of(const VideoWriter& video) {
  core::StateWriter w;
  video.save_state(w);
  return w.take();
}

void load(VideoWriter& video, const std::string& state) {
  core::StateReader r(state, "video.state");
  video.load_state(r);
  EXPECT_TRUE(r.at_end());
}

/// Frames OpenCV reads from `file`, each checked for its size. CAP_ANY is FFmpeg's reader;
/// OpenCV's own (CAP_OPENCV_MJPEG) reads a file of one segment by its idx1 and needs it.
int frames_played(const fs::path& file, int api = cv::CAP_ANY) {
  cv::VideoCapture cap(file.string(), api);
  EXPECT_TRUE(cap.isOpened()) << file;
  int frames = 0;
  cv::Mat image;
  while (cap.read(image)) {
    EXPECT_EQ(image.cols, kWidth);
    EXPECT_EQ(image.rows, kHeight);
    ++frames;
  }
  return frames;
}

}  // namespace

TEST(Video, PlaysWithEveryFrameAndItsBytesFollowFromTheFrames) {
  const TempDir dir("plays");
  const std::string a = straight(dir / "a.avi", 40);
  EXPECT_EQ(frames_played(dir / "a.avi"), 40);
  EXPECT_EQ(frames_played(dir / "a.avi", cv::CAP_OPENCV_MJPEG), 40);
  cv::VideoCapture cap((dir / "a.avi").string());
  EXPECT_DOUBLE_EQ(cap.get(cv::CAP_PROP_FPS), kFps);
  EXPECT_EQ(cap.get(cv::CAP_PROP_FRAME_COUNT), 40);
  EXPECT_EQ(straight(dir / "b.avi", 40), a);  // the same frames, the same bytes
  EXPECT_EQ(a.substr(0, 4), "RIFF");
  EXPECT_NE(a.find("idx1"), std::string::npos);
  EXPECT_EQ(a.find("AVIX"), std::string::npos);  // one segment

  const std::string empty = straight(dir / "empty.avi", 0);  // closed without a frame
  EXPECT_EQ(empty.size(), 4620u + 8u);
  EXPECT_EQ(frames_played(dir / "empty.avi"), 0);
}

// N frames, a checkpoint, M more; then a new writer on the same file (a restarted
// process) restores the checkpoint and writes the same M frames.
TEST(Video, ARestartedWriterContinuesFromTheCheckpointByteIdentical) {
  const TempDir dir("restart");
  constexpr int kN = 17, kM = 23;
  const std::string want = straight(dir / "want.avi", kN + kM);
  const fs::path file = dir / "got.avi";
  std::string state;
  {
    VideoWriter video(file.string(), kFps, kWidth, kHeight);
    for (int k = 0; k < kN; ++k) video.write(frame(k));
    state = state_of(video);
    for (int k = kN; k < kN + kM; ++k) video.write(frame(k));
    // Killed here: the file holds what write() wrote, nothing more.
    const std::string left = bytes_of(file);
    video.discard();
    std::ofstream(file, std::ios::binary) << left;
  }
  {
    // A writer opened to resume leaves the file alone until it is restored.
    const std::string before = bytes_of(file);
    VideoWriter untouched(file.string(), kFps, kWidth, kHeight, VideoWriter::Open::resume);
    untouched.close();
    EXPECT_TRUE(bytes_of(file) == before);
  }
  VideoWriter resumed(file.string(), kFps, kWidth, kHeight, VideoWriter::Open::resume);
  load(resumed, state);
  EXPECT_EQ(resumed.frames(), kN);
  for (int k = kN; k < kN + kM; ++k) resumed.write(frame(k));
  resumed.close();
  EXPECT_TRUE(bytes_of(file) == want) << "the continued file differs";
  EXPECT_EQ(frames_played(file), kN + kM);
}

// A rollback: the same writer goes back to its checkpoint, twice, and on.
TEST(Video, ARollbackInTheSameWriterIsByteIdentical) {
  const TempDir dir("rollback");
  const std::string want = straight(dir / "want.avi", 30);
  const fs::path file = dir / "got.avi";
  VideoWriter video(file.string(), kFps, kWidth, kHeight);
  for (int k = 0; k < 10; ++k) video.write(frame(k));
  const std::string state = state_of(video);
  for (int k = 10; k < 25; ++k) video.write(frame(k));
  load(video, state);
  for (int k = 10; k < 12; ++k) video.write(frame(k));
  load(video, state);
  EXPECT_EQ(state_of(video), state);
  for (int k = 10; k < 30; ++k) video.write(frame(k));
  video.close();
  EXPECT_TRUE(bytes_of(file) == want);
}

// A finished file (the run completed) resumed from an earlier checkpoint: the index and the
// counts close() wrote go, and it ends as before.
TEST(Video, AFinishedFileResumedFromAnEarlierCheckpointIsByteIdentical) {
  const TempDir dir("finished");
  const fs::path file = dir / "v.avi";
  std::string state;
  {
    VideoWriter video(file.string(), kFps, kWidth, kHeight);
    for (int k = 0; k < 12; ++k) video.write(frame(k));
    state = state_of(video);
    for (int k = 12; k < 20; ++k) video.write(frame(k));
    video.close();
  }
  const std::string want = bytes_of(file);
  VideoWriter video(file.string(), kFps, kWidth, kHeight, VideoWriter::Open::resume);
  load(video, state);
  for (int k = 12; k < 20; ++k) video.write(frame(k));
  video.close();
  EXPECT_TRUE(bytes_of(file) == want);
}

// Past segment_bytes the file goes on in OpenDML 'AVIX' segments, each with its own index; a
// checkpoint in any segment (also just before a new one begins) resumes byte-identical.
TEST(Video, OpenDmlSegmentsPlayAndResumeByteIdentical) {
  const TempDir dir("segments");
  constexpr int kFrames = 60;
  const auto options = segments_of(12000);
  const std::string want = straight(dir / "want.avi", kFrames, options);
  std::size_t segments = 0;
  for (auto at = want.find("AVIX"); at != std::string::npos; at = want.find("AVIX", at + 1)) {
    ++segments;
  }
  EXPECT_GE(segments, 3u);
  EXPECT_NE(want.find("indx"), std::string::npos);
  EXPECT_NE(want.find("ix00"), std::string::npos);
  EXPECT_EQ(frames_played(dir / "want.avi"), kFrames);
  cv::VideoCapture cap((dir / "want.avi").string());
  EXPECT_EQ(cap.get(cv::CAP_PROP_FRAME_COUNT), kFrames);

  for (int at = 0; at <= kFrames; at += 7) {
    SCOPED_TRACE(at);
    const fs::path file = dir / "got.avi";
    std::string state;
    {
      VideoWriter video(file.string(), kFps, kWidth, kHeight, VideoWriter::Open::create, options);
      for (int k = 0; k < kFrames; ++k) {
        if (k == at) state = state_of(video);
        video.write(frame(k));
      }
      if (at == kFrames) state = state_of(video);
      video.close();
    }
    VideoWriter video(file.string(), kFps, kWidth, kHeight, VideoWriter::Open::resume, options);
    load(video, state);
    for (int k = at; k < kFrames; ++k) video.write(frame(k));
    video.close();
    EXPECT_TRUE(bytes_of(file) == want);
  }
}

// A process killed while writing leaves a file without index or sizes: OpenCV still plays
// every whole frame in it.
TEST(Video, AnUnfinishedFilePlaysItsWholeFrames) {
  const TempDir dir("unfinished");
  const fs::path file = dir / "v.avi";
  VideoWriter video(file.string(), kFps, kWidth, kHeight);
  for (int k = 0; k < 25; ++k) video.write(frame(k));
  const std::string unfinished = bytes_of(file);
  video.discard();
  std::ofstream(dir / "copy.avi", std::ios::binary) << unfinished;
  EXPECT_EQ(frames_played(dir / "copy.avi"), 25);
  // Killed in the middle of a frame: that frame is lost.
  std::ofstream(dir / "cut.avi", std::ios::binary) << unfinished.substr(0, unfinished.size() - 50);
  EXPECT_EQ(frames_played(dir / "cut.avi"), 24);
}

TEST(Video, ABadFormatOrAnotherFileIsRefusedByName) {
  const TempDir dir("refused");
  const std::string file = (dir / "v.avi").string();
  auto invalid = [&](const std::string& path, double fps, int w, int h, const std::string& part,
                     VideoWriter::Options o = {}) {
    try {
      VideoWriter video(path, fps, w, h, VideoWriter::Open::create, o);
      ADD_FAILURE() << "accepted: " << part;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  invalid((dir / "v.mp4").string(), kFps, kWidth, kHeight, "must end in .avi");
  invalid(file, 0.0, kWidth, kHeight, "fps 0");
  invalid(file, kFps, 0, kHeight, "width 0");
  invalid(file, kFps, kWidth, 40000, "height 40000");
  VideoWriter::Options q;
  q.jpeg_quality = 0;
  invalid(file, kFps, kWidth, kHeight, "jpeg_quality 0", q);
  EXPECT_THROW(
      VideoWriter((dir / "missing.avi").string(), kFps, kWidth, kHeight, VideoWriter::Open::resume),
      std::runtime_error);

  std::string state;
  {
    VideoWriter video(file, kFps, kWidth, kHeight);
    for (int k = 0; k < 8; ++k) video.write(frame(k));
    state = state_of(video);
    RgbImage small = frame(0);
    small.height = kHeight / 2;
    small.pixels.resize(small.pixels.size() / 2);
    EXPECT_THROW(video.write(small), std::runtime_error);
    video.close();
  }
  // Another size, another rate.
  {
    VideoWriter other(file, kFps, kWidth, kHeight + 2, VideoWriter::Open::resume);
    test::expect_state_error([&] { load(other, state); },
                             {"video.state", "v.avi", "64 x 48 px", "64 x 50 px"});
  }
  {
    VideoWriter other(file, 30.0, kWidth, kHeight, VideoWriter::Open::resume);
    test::expect_state_error([&] { load(other, state); }, {"v.avi", "at 15/1 fps"});
  }
  // A file shorter than the checkpoint, and one that holds other frames.
  const std::string whole = bytes_of(file);
  std::ofstream(file, std::ios::binary | std::ios::trunc) << whole.substr(0, 6000);
  {
    VideoWriter other(file, kFps, kWidth, kHeight, VideoWriter::Open::resume);
    test::expect_state_error([&] { load(other, state); },
                             {"v.avi: 6000 bytes, the checkpoint says", "not the run directory"});
  }
  straight(file, 8, [] {
    VideoWriter::Options o;
    o.jpeg_quality = 100;  // larger frames: the file is long enough, its frames are others
    return o;
  }());
  {
    VideoWriter other(file, kFps, kWidth, kHeight, VideoWriter::Open::resume);
    test::expect_state_error([&] { load(other, state); }, {"v.avi", "not the video"});
  }
  {
    VideoWriter::Options o;
    o.jpeg_quality = 100;
    VideoWriter other(file, kFps, kWidth, kHeight, VideoWriter::Open::resume, o);
    test::expect_state_error([&] { load(other, state); }, {"JPEG quality 90", "this one 100"});
  }
}
