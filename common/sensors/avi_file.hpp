#pragma once
// An MJPG AVI file written frame by frame, that a checkpoint can cut back and continue
// (docs/sensors.md, "Video files"; docs/checkpoints.md).
//
// Layout: RIFF 'AVI ' with LIST 'hdrl' (avih, LIST 'strl' with strh 'vids'/'MJPG', strf
// BITMAPINFOHEADER, room for an OpenDML super index, room for LIST 'odml'), LIST 'movi' of
// '00dc' chunks (one JPEG each, padded to even length), idx1. A file that grows past
// `segment_bytes` continues in RIFF 'AVIX' segments (OpenDML): each segment ends with its
// 'ix00' standard index, the first also with idx1, and close() fills in the super index and
// the total frame count.
//
// The bytes of the file are a function of the frames appended, nothing else: a frame goes to
// the end of the file as it comes, the sizes and counts of the header are written by close()
// (while open they are 0, which readers take as "up to the end of the file"), and the index
// entries are kept in memory. So the file is continued from a checkpoint by cutting it back to
// the length the checkpoint recorded (load_state), and a run continued so ends with the same
// bytes as one that never stopped.
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "core/state_io.hpp"

namespace syndds::sensors {

class AviFile {
 public:
  /// Past this many bytes a segment is closed and the next frame opens an 'AVIX' segment
  /// (OpenDML readers' limit of a RIFF segment, as FFmpeg writes them).
  static constexpr std::uint64_t kDefaultSegmentBytes = std::uint64_t{1} << 30;
  /// Segments the super index has room for (256 GiB at the default segment size).
  static constexpr std::size_t kMaxSegments = 256;

  struct Format {
    int width = 0;   // pixels, 1..32767
    int height = 0;  // pixels, 1..32767
    double fps = 0;  // frames per second, > 0 (stored as a ratio of integers, 1/1000 exact)
    std::uint64_t segment_bytes = kDefaultSegmentBytes;  // 1..2^31
  };
  enum class Open {
    create,  // a new file (an existing one is emptied)
    resume,  // the file of a checkpointed run: untouched until load_state() says how it goes on
  };

  /// Throws std::invalid_argument naming `path` and the field for a bad format,
  /// std::runtime_error naming `path` and the system's reason when the file cannot be opened.
  AviFile(std::filesystem::path path, const Format& format, Open open = Open::create);
  /// Closes the file as close() does (errors are lost: call close() to see them).
  ~AviFile();
  AviFile(const AviFile&) = delete;
  AviFile& operator=(const AviFile&) = delete;

  /// Appends one frame (a whole JPEG image). Throws std::runtime_error naming the file.
  void append(std::span<const std::uint8_t> jpeg);
  /// Writes the index and the header's sizes and counts; the file is then complete. Once.
  void close();
  /// Removes the file (a video begun after the checkpoint a run is rolled back to).
  void discard();

  const std::filesystem::path& path() const { return path_; }
  const Format& format() const { return format_; }
  std::size_t frames() const { return chunks_.size(); }
  /// Bytes in the file (before close(): the header and the frames so far).
  std::uint64_t size() const { return end_; }
  bool is_open() const { return fd_ >= 0; }

  /// The file as it is now: its format and the size of every frame (4 bytes a frame; every
  /// offset follows from them).
  void save_state(core::StateWriter& w) const;
  /// Makes the file what it was when save_state() wrote `r`: frames appended since are cut
  /// off (also when the file was closed since), and the next append() continues from there.
  /// Fails through `r` (naming the file) if the format differs or the file does not hold the
  /// frames the state lists (shorter, or another file).
  void load_state(core::StateReader& r);

 private:
  struct Chunk {
    std::uint64_t pos;   // of the '00dc' chunk header
    std::uint32_t size;  // of the JPEG (the chunk holds one more padding byte if odd)
  };
  struct Segment {
    std::uint64_t riff;     // of the 'RIFF' header
    std::uint64_t movi;     // of the 'movi' list type (index offsets count from here)
    std::size_t first;      // index of its first frame in chunks_
    std::size_t count = 0;  // its frames
    std::uint64_t ix = 0;   // of its 'ix00' chunk, once closed in a file of several segments
    std::uint32_t ix_bytes = 0;
    std::uint64_t movi_end = 0;  // end of the 'movi' list, once closed
    std::uint64_t end = 0;       // end of the segment, once closed
    bool closed = false;
  };

  // A file that only lays frames out, writing nothing (load_state replays a checkpoint so).
  struct Layout {};
  AviFile(const AviFile& format_of, Layout);

  // Every change of the file goes through these; with io_ false they only update the layout.
  void put(std::uint64_t at, const std::string& bytes);
  void add_frame(std::span<const std::uint8_t> jpeg, std::uint32_t size);
  void open_segment();
  void close_segment(bool last);
  std::string header(bool complete) const;
  void write_sizes(const Segment& s, bool zero);
  [[noreturn]] void fail(const std::string& what, int error) const;

  std::filesystem::path path_;
  Format format_;
  std::uint32_t rate_ = 0, scale_ = 0;  // fps = rate_ / scale_
  int fd_ = -1;
  bool io_ = true;
  bool restored_ = true;  // false for Open::resume until load_state()
  std::uint64_t end_ = 0;
  std::vector<Chunk> chunks_;
  std::vector<Segment> segments_;
};

}  // namespace syndds::sensors
