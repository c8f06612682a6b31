#include "core/state_io.hpp"

#include <charconv>

#include "core/hash.hpp"

namespace syndds::core {
namespace {

constexpr std::string_view kMagic = "syndds-state 1\n";

}  // namespace

void StateWriter::begin(std::string_view name, std::uint32_t version) {
  io(std::string(name));
  io(version);
  open_.push_back(bytes_.size());
  io(std::uint64_t{0});
}

void StateWriter::end() {
  if (open_.empty()) throw std::logic_error("StateWriter::end without begin");
  const std::size_t at = open_.back();
  open_.pop_back();
  const std::uint64_t length = bytes_.size() - at - sizeof(std::uint64_t);
  std::memcpy(bytes_.data() + at, &length, sizeof length);
}

StateReader::StateReader(std::string_view bytes, std::string source)
    : bytes_(bytes), source_(std::move(source)) {}

void StateReader::fail(const std::string& what) const {
  std::string where = source_;
  for (const auto& o : open_) where += (where.empty() ? "" : ": ") + std::string("section '") +
                                       o.name + "'";
  throw StateError(where + ": " + what + " (at byte " + std::to_string(pos_) + " of " +
                   std::to_string(bytes_.size()) + ")");
}

const char* StateReader::take(std::size_t n, const char* what) {
  const std::size_t limit = open_.empty() ? bytes_.size() : open_.back().end;
  if (n > limit - pos_) {
    fail(std::string("the state ends inside ") + what + " (" + std::to_string(n) +
         " bytes wanted, " + std::to_string(limit - pos_) + " left)");
  }
  const char* p = bytes_.data() + pos_;
  pos_ += n;
  return p;
}

std::size_t StateReader::count(const char* what) {
  std::uint64_t n = 0;
  io(n);
  const std::size_t limit = open_.empty() ? bytes_.size() : open_.back().end;
  if (n > limit - pos_) {
    // Every element takes at least one byte: a count beyond the bytes left is damage.
    fail(std::string("the length of ") + what + " (" + std::to_string(n) +
         ") is more than the bytes left");
  }
  return static_cast<std::size_t>(n);
}

std::uint32_t StateReader::begin(std::string_view name, std::uint32_t newest,
                                 std::uint32_t oldest) {
  const std::size_t at = pos_;
  std::string found;
  io(found);
  if (found != name) {
    pos_ = at;
    fail("expected section '" + std::string(name) + "', found '" + found + "'");
  }
  std::uint32_t version = 0;
  io(version);
  if (version < oldest || version > newest) {
    fail("section '" + found + "' has format version " + std::to_string(version) +
         "; this build reads versions " + std::to_string(oldest) + " to " +
         std::to_string(newest));
  }
  std::uint64_t length = 0;
  io(length);
  const std::size_t limit = open_.empty() ? bytes_.size() : open_.back().end;
  if (length > limit - pos_) {
    fail("section '" + found + "' claims " + std::to_string(length) + " bytes, " +
         std::to_string(limit - pos_) + " are left");
  }
  open_.push_back({found, pos_ + static_cast<std::size_t>(length)});
  return version;
}

void StateReader::end() {
  if (open_.empty()) throw std::logic_error("StateReader::end without begin");
  if (pos_ != open_.back().end) {
    fail(std::to_string(open_.back().end - pos_) +
         " bytes of the section were not read: the state was written by a different format");
  }
  open_.pop_back();
}

std::string frame_state(const std::string& state) {
  Fnv1a64 h;
  h.add_bytes(state.data(), state.size());
  std::string out(kMagic);
  out += std::to_string(state.size()) + " " + hex64(h.value()) + "\n";
  out += state;
  return out;
}

std::string unframe_state(std::string_view framed, const std::string& source) {
  if (framed.substr(0, kMagic.size()) != kMagic) {
    throw StateError(source + ": not a syndds state file (the first line is not '" +
                     std::string(kMagic.substr(0, kMagic.size() - 1)) + "')");
  }
  framed.remove_prefix(kMagic.size());
  const auto nl = framed.find('\n');
  if (nl == std::string_view::npos) throw StateError(source + ": the header line is cut off");
  const std::string header(framed.substr(0, nl));
  framed.remove_prefix(nl + 1);
  // "<byte count> <16 lowercase hexadecimal digits>", exactly as frame_state writes it.
  std::uint64_t size = 0;
  const auto space = header.find(' ');
  const std::string_view count = std::string_view(header).substr(0, space);
  const auto [end, error] = std::from_chars(count.data(), count.data() + count.size(), size);
  const std::string hex = space == std::string::npos ? "" : header.substr(space + 1);
  if (count.empty() || error != std::errc() || end != count.data() + count.size() ||
      hex.size() != 16 || hex.find_first_not_of("0123456789abcdef") != std::string::npos) {
    throw StateError(source + ": malformed header '" + header +
                     "' (expected the byte count and a 16-digit hexadecimal checksum)");
  }
  if (framed.size() != size) {
    throw StateError(source + ": " + std::to_string(framed.size()) + " bytes of state, the header says " +
                     std::to_string(size) + " (the file is truncated or was appended to)");
  }
  Fnv1a64 h;
  h.add_bytes(framed.data(), framed.size());
  if (hex64(h.value()) != hex) {
    throw StateError(source + ": checksum " + hex64(h.value()) + " does not match the header's " +
                     hex + " (the file is damaged)");
  }
  return std::string(framed);
}

}  // namespace syndds::core
