#include "sensors/avi_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace syndds::sensors {
namespace fs = std::filesystem;
namespace {

// Where the parts of the first segment's header are (the header has a fixed size).
constexpr std::uint64_t kIndxBytes = 24 + 16 * AviFile::kMaxSegments;  // super index chunk
constexpr std::uint64_t kIndxAt = 212;                                 // 'JUNK' / 'indx'
constexpr std::uint64_t kOdmlBytes = 4 + 8 + 248;                      // 'odml' + dmlh chunk
constexpr std::uint64_t kOdmlAt = kIndxAt + 8 + kIndxBytes;            // 'JUNK' / 'LIST'
constexpr std::uint64_t kMoviListAt = kOdmlAt + 8 + kOdmlBytes;        // 'LIST' .... 'movi'
constexpr std::uint64_t kHeaderBytes = kMoviListAt + 12;               // the first frame
constexpr std::uint64_t kAvixHeaderBytes = 24;  // 'RIFF' .... 'AVIX' 'LIST' .... 'movi'

constexpr std::uint32_t kAvifFlags = 0x10 | 0x100 | 0x800;  // HASINDEX ISINTERLEAVED TRUSTCKTYPE
constexpr std::uint32_t kIndexKeyFrame = 0x10;              // AVIIF_KEYFRAME

// Little-endian bytes of a RIFF structure.
class Bytes {
 public:
  Bytes& u8(std::uint8_t v) {
    s_.push_back(static_cast<char>(v));
    return *this;
  }
  Bytes& u16(std::uint16_t v) { return u8(v & 0xff).u8(static_cast<std::uint8_t>(v >> 8)); }
  Bytes& u32(std::uint32_t v) { return u16(v & 0xffff).u16(static_cast<std::uint16_t>(v >> 16)); }
  Bytes& u64(std::uint64_t v) {
    return u32(v & 0xffffffff).u32(static_cast<std::uint32_t>(v >> 32));
  }
  Bytes& cc(const char (&fourcc)[5]) {
    s_.append(fourcc, 4);
    return *this;
  }
  Bytes& zeros(std::size_t n) {
    s_.append(n, '\0');
    return *this;
  }
  std::size_t size() const { return s_.size(); }
  const std::string& str() const { return s_; }

 private:
  std::string s_;
};

std::uint32_t u32_of(std::uint64_t v) { return static_cast<std::uint32_t>(v); }

std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

AviFile::AviFile(fs::path path, const Format& format, Open open)
    : path_(std::move(path)), format_(format) {
  const std::string name = path_.string();
  auto bad = [&](const std::string& what) { throw std::invalid_argument(name + ": " + what); };
  if (format.width < 1 || format.width > 32767) {
    bad("width " + std::to_string(format.width) + " px is outside 1..32767");
  }
  if (format.height < 1 || format.height > 32767) {
    bad("height " + std::to_string(format.height) + " px is outside 1..32767");
  }
  if (!std::isfinite(format.fps) || format.fps < 0.001 || format.fps > 1.0e6) {
    bad("fps " + number(format.fps) + " is outside 0.001..1e6");
  }
  if (format.segment_bytes < 1 || format.segment_bytes > (std::uint64_t{1} << 31)) {
    bad("segment_bytes " + std::to_string(format.segment_bytes) + " is outside 1..2^31");
  }
  std::uint64_t rate = static_cast<std::uint64_t>(std::llround(format.fps * 1000.0));
  std::uint64_t scale = 1000;
  const std::uint64_t g = std::gcd(rate, scale);
  rate_ = u32_of(rate / g);
  scale_ = u32_of(scale / g);
  if (open == Open::create) {
    if (path_.has_parent_path()) {
      std::error_code ec;
      fs::create_directories(path_.parent_path(), ec);
      if (ec) throw std::runtime_error(name + ": cannot create its directory: " + ec.message());
    }
    fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) fail("cannot create", errno);
    open_segment();
  } else {
    fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
    if (fd_ < 0) fail("cannot reopen the video of the checkpointed run", errno);
    restored_ = false;
  }
}

AviFile::~AviFile() {
  try {
    close();
  } catch (const std::exception&) {
    // close() is where a caller sees the error; a destructor cannot report it.
  }
}

void AviFile::fail(const std::string& what, int error) const {
  throw std::runtime_error(path_.string() + ": " + what + ": " + std::strerror(error));
}

void AviFile::put(std::uint64_t at, const std::string& bytes) {
  if (!io_) return;
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n =
        ::pwrite(fd_, bytes.data() + done, bytes.size() - done, static_cast<off_t>(at + done));
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("cannot write", errno);
    }
    if (n == 0) fail("cannot write", EIO);
    done += static_cast<std::size_t>(n);
  }
}

std::string AviFile::header(bool complete) const {
  const Segment& first = segments_.front();
  const bool several = complete && segments_.size() > 1;
  std::uint32_t largest = 0;
  if (complete) {
    for (const auto& c : chunks_) largest = std::max(largest, c.size);
  }
  const auto w = static_cast<std::uint32_t>(format_.width);
  const auto h = static_cast<std::uint32_t>(format_.height);
  const auto usec = u32_of(static_cast<std::uint64_t>(
      std::llround(1.0e6 * static_cast<double>(scale_) / static_cast<double>(rate_))));
  Bytes b;
  b.cc("RIFF").u32(first.closed ? u32_of(first.end - first.riff - 8) : 0).cc("AVI ");
  b.cc("LIST").u32(u32_of(kMoviListAt - 20)).cc("hdrl");
  b.cc("avih").u32(56);
  b.u32(usec).u32(0).u32(0).u32(kAvifFlags);
  b.u32(complete ? u32_of(first.count) : 0).u32(0).u32(1).u32(largest);
  b.u32(w).u32(h).zeros(16);
  b.cc("LIST").u32(u32_of(kOdmlAt - 96)).cc("strl");
  b.cc("strh").u32(56).cc("vids").cc("MJPG").u32(0).u16(0).u16(0).u32(0);
  b.u32(scale_).u32(rate_).u32(0).u32(complete ? u32_of(chunks_.size()) : 0);
  b.u32(largest).u32(0xffffffff).u32(0);
  b.u16(0).u16(0).u16(static_cast<std::uint16_t>(w)).u16(static_cast<std::uint16_t>(h));
  b.cc("strf").u32(40).u32(40).u32(w).u32(h).u16(1).u16(24).cc("MJPG").u32(w * h * 3);
  b.zeros(16);
  if (several) {
    b.cc("indx").u32(u32_of(kIndxBytes)).u16(4).u8(0).u8(0);
    b.u32(u32_of(segments_.size())).cc("00dc").zeros(12);
    for (const auto& s : segments_) b.u64(s.ix).u32(s.ix_bytes).u32(u32_of(s.count));
    b.zeros(16 * (kMaxSegments - segments_.size()));
    b.cc("LIST");
  } else {
    b.cc("JUNK").u32(u32_of(kIndxBytes)).zeros(kIndxBytes);
    b.cc("JUNK");
  }
  b.u32(u32_of(kOdmlBytes)).cc("odml").cc("dmlh").u32(248);
  b.u32(several ? u32_of(chunks_.size()) : 0).zeros(244);
  b.cc("LIST").u32(first.closed ? u32_of(first.movi_end - first.movi) : 0).cc("movi");
  if (b.size() != kHeaderBytes) throw std::logic_error("AVI header of the wrong size");
  return b.str();
}

void AviFile::open_segment() {
  Segment s;
  s.first = chunks_.size();
  if (segments_.empty()) {
    s.riff = 0;
    s.movi = kMoviListAt + 8;
    segments_.push_back(s);
    put(0, header(false));
    end_ = kHeaderBytes;
    return;
  }
  s.riff = end_;
  s.movi = end_ + 20;
  segments_.push_back(s);
  Bytes b;
  b.cc("RIFF").u32(0).cc("AVIX").cc("LIST").u32(0).cc("movi");
  put(end_, b.str());
  end_ += kAvixHeaderBytes;
}

void AviFile::write_sizes(const Segment& s, bool zero) {
  put(s.riff + 4, Bytes().u32(zero ? 0 : u32_of(s.end - s.riff - 8)).str());
  put(s.movi - 4, Bytes().u32(zero ? 0 : u32_of(s.movi_end - s.movi)).str());
}

void AviFile::close_segment(bool last) {
  Segment& s = segments_.back();
  if (segments_.size() > 1 || !last) {
    // A file of several segments: each gets its standard index ('ix00', OpenDML).
    Bytes ix;
    ix.cc("ix00").u32(u32_of(24 + 8 * s.count)).u16(2).u8(0).u8(1);
    ix.u32(u32_of(s.count)).cc("00dc").u64(s.movi).u32(0);
    for (std::size_t k = s.first; k < s.first + s.count; ++k) {
      ix.u32(u32_of(chunks_[k].pos + 8 - s.movi)).u32(chunks_[k].size);
    }
    s.ix = end_;
    s.ix_bytes = u32_of(ix.size());
    put(end_, ix.str());
    end_ += ix.size();
  }
  s.movi_end = end_;
  if (segments_.size() == 1) {
    Bytes idx;
    idx.cc("idx1").u32(u32_of(16 * s.count));
    for (std::size_t k = s.first; k < s.first + s.count; ++k) {
      idx.cc("00dc").u32(kIndexKeyFrame).u32(u32_of(chunks_[k].pos - s.movi)).u32(chunks_[k].size);
    }
    put(end_, idx.str());
    end_ += idx.size();
  }
  s.end = end_;
  s.closed = true;
  write_sizes(s, false);
}

void AviFile::add_frame(std::span<const std::uint8_t> jpeg, std::uint32_t size) {
  if (segments_.back().count > 0 && end_ - segments_.back().riff >= format_.segment_bytes) {
    if (segments_.size() == kMaxSegments) {
      throw std::runtime_error(path_.string() + ": the video is full (" +
                               std::to_string(kMaxSegments) + " segments of " +
                               std::to_string(format_.segment_bytes) + " bytes)");
    }
    close_segment(false);
    open_segment();
  }
  if (io_) {
    std::string chunk = Bytes().cc("00dc").u32(size).str();
    chunk.append(reinterpret_cast<const char*>(jpeg.data()), jpeg.size());
    if (size % 2 != 0) chunk.push_back('\0');
    put(end_, chunk);
  }
  chunks_.push_back({end_, size});
  ++segments_.back().count;
  end_ += 8 + std::uint64_t{size} + size % 2;
}

void AviFile::append(std::span<const std::uint8_t> jpeg) {
  if (fd_ < 0) throw std::logic_error(path_.string() + ": frame appended after close");
  if (!restored_) throw std::logic_error(path_.string() + ": frame appended before load_state");
  if (jpeg.size() >= 0x7fffffffu) throw std::runtime_error(path_.string() + ": frame too large");
  add_frame(jpeg, u32_of(jpeg.size()));
}

void AviFile::close() {
  if (fd_ < 0) return;
  struct Release {  // the descriptor is given up also when finishing the file fails
    AviFile& f;
    ~Release() {
      if (f.fd_ >= 0) ::close(f.fd_);
      f.fd_ = -1;
    }
  } release{*this};
  if (restored_) {
    close_segment(true);
    put(0, header(true));
  }
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail("cannot close", errno);
}

void AviFile::discard() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  std::error_code ec;
  fs::remove(path_, ec);
  if (ec) throw std::runtime_error(path_.string() + ": cannot remove: " + ec.message());
}

void AviFile::save_state(core::StateWriter& w) const {
  if (!restored_) throw std::logic_error(path_.string() + ": state saved before load_state");
  if (fd_ < 0) throw std::logic_error(path_.string() + ": state saved after close");
  w.begin("avi_file", 1);
  w.io(format_.width);
  w.io(format_.height);
  w.io(rate_);
  w.io(scale_);
  w.io(format_.segment_bytes);
  std::vector<std::uint32_t> sizes;
  sizes.reserve(chunks_.size());
  for (const auto& c : chunks_) sizes.push_back(c.size);
  w.io(sizes);
  w.io(end_);
  w.end();
}

void AviFile::load_state(core::StateReader& r) {
  const std::string name = path_.string();
  r.begin("avi_file", 1, 1);
  const auto width = r.get<int>();
  const auto height = r.get<int>();
  const auto rate = r.get<std::uint32_t>();
  const auto scale = r.get<std::uint32_t>();
  const auto segment_bytes = r.get<std::uint64_t>();
  if (width != format_.width || height != format_.height || rate != rate_ || scale != scale_ ||
      segment_bytes != format_.segment_bytes) {
    r.fail(name + ": the checkpoint's video is " + std::to_string(width) + " x " +
           std::to_string(height) + " px at " + std::to_string(rate) + "/" + std::to_string(scale) +
           " fps in segments of " + std::to_string(segment_bytes) + " bytes, this one " +
           std::to_string(format_.width) + " x " + std::to_string(format_.height) + " px at " +
           std::to_string(rate_) + "/" + std::to_string(scale_) + " fps in segments of " +
           std::to_string(format_.segment_bytes) + " bytes");
  }
  const auto sizes = r.get<std::vector<std::uint32_t>>();
  const auto end = r.get<std::uint64_t>();
  // The layout of those frames, found without writing anything; this object stays as it was
  // until the file is known to hold them.
  AviFile layout(*this, Layout{});
  try {
    layout.open_segment();
    for (const auto size : sizes) layout.add_frame({}, size);
  } catch (const std::runtime_error& e) {
    r.fail(e.what());
  }
  if (layout.end_ != end) {
    r.fail(name + ": " + std::to_string(sizes.size()) + " frames make " +
           std::to_string(layout.end_) + " bytes, the checkpoint says " + std::to_string(end));
  }
  if (fd_ < 0) {
    fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
    if (fd_ < 0) r.fail(name + ": cannot reopen: " + std::strerror(errno));
  }
  struct stat st {};
  if (::fstat(fd_, &st) != 0) r.fail(name + ": cannot stat: " + std::strerror(errno));
  const auto length = static_cast<std::uint64_t>(st.st_size);
  if (length < end) {
    r.fail(name + ": " + std::to_string(length) + " bytes, the checkpoint says " +
           std::to_string(end) + " (not the run directory that was checkpointed?)");
  }
  // The file must hold the checkpoint's frames where they were written: its RIFF header and
  // the header of the last frame.
  auto holds = [&](std::uint64_t at, const std::string& expected) {
    std::string got(expected.size(), '\0');
    return ::pread(fd_, got.data(), got.size(), static_cast<off_t>(at)) ==
               static_cast<ssize_t>(got.size()) &&
           got == expected;
  };
  if (!holds(0, "RIFF") || !holds(8, "AVI ")) r.fail(name + ": not an AVI file");
  const auto& chunks = layout.chunks_;
  if (!chunks.empty() &&
      !holds(chunks.back().pos, Bytes().cc("00dc").u32(chunks.back().size).str())) {
    r.fail(name + ": frame " + std::to_string(chunks.size()) +
           " of the checkpoint is not in the file (not the video that was checkpointed?)");
  }
  r.end();
  chunks_ = std::move(layout.chunks_);
  segments_ = std::move(layout.segments_);
  end_ = end;
  restored_ = true;
  if (::ftruncate(fd_, static_cast<off_t>(end)) != 0) fail("cannot cut back", errno);
  // The header as it was while the file was written: closing the file since filled it in.
  put(0, header(false));
  if (segments_.size() > 1) write_sizes(segments_.back(), true);
}

AviFile::AviFile(const AviFile& other, Layout)
    : path_(other.path_),
      format_(other.format_),
      rate_(other.rate_),
      scale_(other.scale_),
      io_(false) {}

}  // namespace syndds::sensors
