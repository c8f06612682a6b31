#pragma once
// Binary state of a component for checkpoints (docs/checkpoints.md): a StateWriter appends
// values, a StateReader reads them back in the same order. Numbers are stored as their exact
// bytes (little-endian, as on every machine syndds builds on), so a restored double is the same
// double, bit for bit. Components wrap their state in named, versioned sections; a section
// records its length, so a reader that disagrees with the writer is stopped at the section's
// end with a message naming the section, instead of reading garbage further on.
//
// A component can write its save and load once, for both directions:
//
//   template <typename Archive> void state(Archive& a) { a.begin("pid", 1); a.io(integral_); a.end(); }
//
// StateWriter::io writes, StateReader::io reads (the writer takes a const reference; call it on
// a const_cast'ed object or write save/load apart).
#include <bit>
#include <cstdint>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace syndds::core {

static_assert(std::endian::native == std::endian::little,
              "checkpoint files store numbers little-endian as they are in memory");

/// A state that cannot be read: the message names the source (e.g. the file), the section and
/// the byte offset.
class StateError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

template <typename T>
concept StatePod = std::is_arithmetic_v<T> || std::is_enum_v<T>;

class StateWriter {
 public:
  template <StatePod T>
  void io(const T& v) {
    if constexpr (std::is_same_v<T, bool>) {
      bytes_.push_back(v ? 1 : 0);
    } else {
      char b[sizeof(T)];
      std::memcpy(b, &v, sizeof(T));
      bytes_.append(b, sizeof(T));
    }
  }
  void io(const std::string& s) {
    io(static_cast<std::uint64_t>(s.size()));
    bytes_.append(s);
  }
  template <typename T>
  void io(const std::vector<T>& v) {
    io(static_cast<std::uint64_t>(v.size()));
    if constexpr (StatePod<T> && !std::is_same_v<T, bool>) {
      bytes_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
    } else {
      for (const auto& x : v) io(x);
    }
  }
  template <typename Scalar, int Rows, int Cols, int Options, int MaxRows, int MaxCols>
  void io(const Eigen::Matrix<Scalar, Rows, Cols, Options, MaxRows, MaxCols>& m) {
    static_assert(Rows > 0 && Cols > 0, "only fixed-size Eigen matrices");
    for (int i = 0; i < m.size(); ++i) io(m.data()[i]);
  }
  template <typename Scalar, int Options>
  void io(const Eigen::Quaternion<Scalar, Options>& q) {
    io(q.coeffs());
  }
  template <typename T>
  void io(const std::optional<T>& o) {
    io(o.has_value());
    if (o) io(*o);
  }
  /// Anything with a `void state(StateWriter&) const` member.
  template <typename T>
    requires requires(const T& t, StateWriter& w) { t.state(w); }
  void io(const T& t) {
    t.state(*this);
  }

  /// Opens a section: its name, its format version, then its length (patched by end()).
  void begin(std::string_view name, std::uint32_t version);
  void end();

  const std::string& bytes() const { return bytes_; }
  std::string take() { return std::move(bytes_); }

 private:
  std::string bytes_;
  std::vector<std::size_t> open_;  // offsets of the open sections' length fields
};

class StateReader {
 public:
  /// `source` names where the bytes came from in error messages (e.g. a file path).
  StateReader(std::string_view bytes, std::string source);

  template <StatePod T>
  void io(T& v) {
    if constexpr (std::is_same_v<T, bool>) {
      const char* p = take(1, "a flag");
      if (*p != 0 && *p != 1) fail("a flag is neither 0 nor 1");
      v = *p == 1;
    } else {
      std::memcpy(&v, take(sizeof(T), "a number"), sizeof(T));
    }
  }
  void io(std::string& s) {
    const std::size_t n = count("a string");
    s.assign(take(n, "a string"), n);
  }
  template <typename T>
  void io(std::vector<T>& v) {
    const std::size_t n = count("a list");
    if constexpr (StatePod<T> && !std::is_same_v<T, bool>) {
      v.resize(n);
      std::memcpy(v.data(), take(n * sizeof(T), "a list"), n * sizeof(T));
    } else {
      v.clear();
      v.reserve(n);
      for (std::size_t i = 0; i < n; ++i) {
        T x{};
        io(x);
        v.push_back(std::move(x));
      }
    }
  }
  template <typename Scalar, int Rows, int Cols, int Options, int MaxRows, int MaxCols>
  void io(Eigen::Matrix<Scalar, Rows, Cols, Options, MaxRows, MaxCols>& m) {
    static_assert(Rows > 0 && Cols > 0, "only fixed-size Eigen matrices");
    for (int i = 0; i < m.size(); ++i) io(m.data()[i]);
  }
  template <typename Scalar, int Options>
  void io(Eigen::Quaternion<Scalar, Options>& q) {
    io(q.coeffs());
  }
  template <typename T>
  void io(std::optional<T>& o) {
    if (get<bool>()) {
      T v{};
      io(v);
      o = std::move(v);
    } else {
      o.reset();
    }
  }
  template <typename T>
    requires requires(T& t, StateReader& r) { t.state(r); }
  void io(T& t) {
    t.state(*this);
  }
  /// Reads a value of type T (e.g. `auto n = r.get<std::int64_t>()`).
  template <typename T>
  T get() {
    T v{};
    io(v);
    return v;
  }

  /// Enters a section written as begin(name, version); throws unless the name matches and the
  /// version is one of [oldest, newest]. Returns the version found.
  std::uint32_t begin(std::string_view name, std::uint32_t newest, std::uint32_t oldest = 0);
  /// Throws unless the section was read exactly to its end.
  void end();
  bool at_end() const { return pos_ == bytes_.size(); }
  std::size_t position() const { return pos_; }
  /// Throws a StateError naming the source, the open sections and the byte offset.
  [[noreturn]] void fail(const std::string& what) const;

 private:
  const char* take(std::size_t n, const char* what);
  std::size_t count(const char* what);

  struct Open {
    std::string name;
    std::size_t end;
  };
  std::string_view bytes_;
  std::string source_;
  std::size_t pos_ = 0;
  std::vector<Open> open_;
};

/// Bytes of `state` framed for a file: a magic line, the byte count and a checksum (FNV-1a 64)
/// of the bytes, so a truncated or damaged file is refused on load.
std::string frame_state(const std::string& state);
/// The bytes framed by frame_state; throws StateError naming `source` if damaged.
std::string unframe_state(std::string_view framed, const std::string& source);

}  // namespace syndds::core
