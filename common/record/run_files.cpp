#include "record/run_files.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace syndds::record {
namespace fs = std::filesystem;
namespace {

std::string reason(int error) { return std::strerror(error); }

// Writes all of `bytes` to `fd` (write(2) may take less than asked); returns 0 or the errno.
int write_all(int fd, std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (n == 0) return EIO;  // never for regular files; do not spin
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
  return 0;
}

}  // namespace

std::string csv_escape(std::string_view text) {
  if (text.find_first_of(",\"\r\n") == std::string_view::npos) return std::string(text);
  std::string out = "\"";
  for (char c : text) {
    if (c == '"') out += '"';
    out += c;
  }
  out += '"';
  return out;
}

OutputFile::OutputFile(fs::path path, Open open) : path_(std::move(path)) {
  // O_APPEND: after a truncate() the next write goes to the new end, never leaving a hole.
  if (open == Open::create) {
    fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
    if (fd_ < 0) fail("cannot create", errno);
  } else {
    fd_ = ::open(path_.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
    if (fd_ < 0) fail("cannot reopen the file of the checkpointed run", errno);
    const off_t end = ::lseek(fd_, 0, SEEK_END);
    if (end < 0) fail("cannot find the end", errno);
    size_ = static_cast<std::uint64_t>(end);
  }
}

OutputFile::~OutputFile() {
  if (fd_ >= 0) ::close(fd_);  // errors of an abandoned file: close() is where they are seen
}

void OutputFile::fail(const char* what, int error) const {
  throw WriteError(path_.string() + ": " + what + ": " + reason(error));
}

void OutputFile::write(std::string_view bytes) {
  if (fd_ < 0) throw std::logic_error(path_.string() + ": written after close");
  const int error = write_all(fd_, bytes);
  if (error != 0) {
    // Part of `bytes` may be in the file: the size is what it holds, whatever that is.
    const off_t end = ::lseek(fd_, 0, SEEK_END);
    if (end >= 0) size_ = static_cast<std::uint64_t>(end);
    fail("cannot write", error);
  }
  size_ += bytes.size();
}

void OutputFile::truncate(std::uint64_t size) {
  if (::ftruncate(fd_, static_cast<off_t>(size)) != 0) fail("cannot cut back", errno);
  size_ = size;
}

void OutputFile::sync() {
  if (::fsync(fd_) != 0) fail("cannot sync", errno);
}

void OutputFile::close() {
  if (fd_ < 0) return;
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail("cannot close", errno);
}

CsvFile::CsvFile(fs::path path, std::vector<std::string> columns, OutputFile::Open open)
    : file_(std::move(path), open), columns_(std::move(columns)) {
  if (open == OutputFile::Open::resume) return;
  std::string header;
  for (const auto& c : columns_) {
    if (!header.empty()) header += ',';
    header += csv_escape(c);
  }
  header += '\n';
  file_.write(header);
}

void CsvFile::append_cell(std::string_view text) {
  if (text.find_first_of(",\"\r\n") == std::string_view::npos) {
    pending_.append(text);
  } else {
    const std::string quoted = csv_escape(text);
    pending_.append(std::string_view(quoted));
  }
}

void CsvFile::wrong_arity(std::size_t cells) const {
  throw std::logic_error(path().string() + ": a row of " + std::to_string(cells) + " cells for " +
                         std::to_string(columns_.size()) + " columns");
}

void CsvFile::commit() { commit_rows({this}); }

void CsvFile::cut_to(std::uint64_t size) {
  if (size > file_.size()) {
    throw WriteError(path().string() + ": " + std::to_string(file_.size()) +
                     " bytes, the checkpoint says " + std::to_string(size) +
                     " (not the run directory that was checkpointed?)");
  }
  pending_.clear();
  file_.truncate(size);
}

void commit_rows(std::initializer_list<CsvFile*> files) {
  std::vector<std::pair<CsvFile*, std::uint64_t>> before;
  try {
    for (CsvFile* f : files) {
      if (!f || f->pending_.size() == 0) continue;
      before.emplace_back(f, f->file_.size());
      f->file_.write(std::string_view(f->pending_.data(), f->pending_.size()));
      f->pending_.clear();
    }
  } catch (const WriteError&) {
    for (CsvFile* f : files) {
      if (f) f->pending_.clear();
    }
    for (auto& [f, size] : before) {
      try {
        f->file_.truncate(size);
      } catch (const WriteError&) {
        // Not a regular file (e.g. a device): nothing to cut back; the first error is the news.
      }
    }
    throw;
  }
}

SpaceReserve::SpaceReserve(fs::path path, std::uint64_t bytes) : path_(std::move(path)) {
  const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw WriteError(path_.string() + ": cannot create: " + reason(errno));
  const int error = ::posix_fallocate(fd, 0, static_cast<off_t>(bytes));  // not via errno
  ::close(fd);
  if (error != 0) {
    ::unlink(path_.c_str());
    throw WriteError(path_.string() + ": cannot reserve " + std::to_string(bytes) +
                     " bytes: " + reason(error));
  }
  held_ = true;
}

void SpaceReserve::release() {
  if (!held_) return;
  held_ = false;
  ::unlink(path_.c_str());
}

void write_file_atomically(const fs::path& path, std::string_view bytes) {
  const fs::path tmp = path.string() + ".tmp";
  try {
    OutputFile out(tmp);
    out.write(bytes);
    out.sync();
    out.close();
  } catch (const WriteError&) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw;
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw WriteError(path.string() + ": cannot replace: " + ec.message());
  }
  sync_directory(path.has_parent_path() ? path.parent_path() : fs::path("."));
}

void sync_directory(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) {
    throw WriteError(dir.string() + ": cannot open the directory to sync it: " + reason(errno));
  }
  const int error = ::fsync(fd) == 0 ? 0 : errno;
  ::close(fd);
  if (error != 0 && error != EINVAL) {
    throw WriteError(dir.string() + ": cannot sync the directory: " + reason(error));
  }
}

void create_directories_durably(const fs::path& dir) {
  std::error_code ec;
  if (fs::is_directory(dir, ec)) return;
  const fs::path parent = dir.has_parent_path() ? dir.parent_path() : fs::path(".");
  if (parent != dir) create_directories_durably(parent);
  // Another process may create it at the same moment: either way it exists, and the process
  // that created it syncs its parent before it writes into it (so once every member reported
  // its file of a checkpoint, every directory on the way is on the disk).
  if (fs::create_directory(dir, ec)) {
    sync_directory(parent);
  } else if (ec) {
    throw WriteError(dir.string() + ": cannot create: " + ec.message());
  }
}

}  // namespace syndds::record
