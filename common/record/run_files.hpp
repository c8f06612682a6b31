#pragma once
// The run-directory writer: the one way every file of a run directory is written (the recorder's
// CSV files and summaries, the sensors' frame index, the terrain images, test logs).
//
//  - Every write, flush and close is checked; a failure throws WriteError naming the file and
//    the system's reason (a full disk must end the run, not leave it "completed" and truncated).
//  - A CSV file has one column list: the header is written from it and a row with a different
//    number of cells is a programming error (std::logic_error). Text cells are quoted as RFC 4180
//    asks when they hold a comma, a quote or a line break, so ids can never shift columns.
//  - Rows are gathered and written per frame: commit_rows() writes one frame's rows of several
//    files, and when any write fails every file is cut back to the end of the previous frame, so
//    the files never hold part of a frame.
//  - Summaries are replaced atomically (temporary file in the same directory, fsync, rename,
//    fsync of the directory): a reader, or a run killed at any moment, sees the old or the new
//    file, never a partial one; a SpaceReserve keeps room for the last one on a disk that fills
//    up.
//
// No DDS and nothing heavy here: every layer above (agents, scm, services) may use it.
#include <fmt/format.h>

#include <charconv>
#include <concepts>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace syndds::record {

/// A file of the run directory could not be written (the message names it and says why).
class WriteError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A number written with `digits` significant digits ("{:.<digits>g}").
template <std::floating_point T>
struct Sig {
  T value;
  int digits;
};
template <std::floating_point T>
Sig(T, int) -> Sig<T>;

/// A number written with `digits` digits after the point ("{:.<digits>f}").
template <std::floating_point T>
struct Fixed {
  T value;
  int digits;
};
template <std::floating_point T>
Fixed(T, int) -> Fixed<T>;

/// A text cell as RFC 4180 writes it: quoted (quotes doubled) if it holds ',', '"', CR or LF.
std::string csv_escape(std::string_view text);

/// A file opened for appending, closed when destroyed. Every write is checked.
class OutputFile {
 public:
  enum class Open {
    create,  // a new file (an existing one is emptied)
    resume,  // an existing file of a checkpointed run, appended to (truncate() cuts it back)
  };
  /// Creates (truncates) `path`, or reopens it to append. Throws WriteError if it cannot.
  explicit OutputFile(std::filesystem::path path, Open open = Open::create);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  const std::filesystem::path& path() const { return path_; }
  /// Bytes in the file (everything written through this object).
  std::uint64_t size() const { return size_; }
  /// Appends all of `bytes` (the kernel has them when this returns).
  void write(std::string_view bytes);
  /// Cuts the file back to `size` bytes (undoing a write that failed part way).
  void truncate(std::uint64_t size);
  /// Forces the written bytes to the disk.
  void sync();
  /// Closes the file, reporting an error the destructor would have to swallow.
  void close();

 private:
  [[noreturn]] void fail(const char* what, int error) const;

  std::filesystem::path path_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

/// A CSV file with a fixed column list. Rows go to a buffer; commit() (or commit_rows() for
/// the files of one frame together) writes them.
class CsvFile {
 public:
  /// Creates `path` and writes the header: the column names, comma-separated. With
  /// Open::resume the file of a checkpointed run is reopened as it is (cut_to() trims it).
  CsvFile(std::filesystem::path path, std::vector<std::string> columns,
          OutputFile::Open open = OutputFile::Open::create);

  const std::filesystem::path& path() const { return file_.path(); }
  /// Bytes in the file (header and committed rows).
  std::uint64_t size() const { return file_.size(); }
  /// Cuts the file back to `size` bytes (a checkpoint's end of a frame); rows not committed
  /// are dropped. Throws WriteError if the file is shorter.
  void cut_to(std::uint64_t size);
  const std::vector<std::string>& columns() const { return columns_; }

  /// Adds one row to the buffer. Cells: integers, floating-point numbers (9 significant digits
  /// unless wrapped in Sig / Fixed), text (escaped). Exactly one cell per column.
  template <typename... Cells>
  void row(const Cells&... cells) {
    if (sizeof...(Cells) != columns_.size()) wrong_arity(sizeof...(Cells));
    bool first = true;
    ((append_separator(first), append_cell(cells)), ...);
    pending_.push_back('\n');
  }

  bool has_pending() const { return pending_.size() > 0; }
  /// Writes the buffered rows (all or, after a failure, none of them: see commit_rows()).
  void commit();
  void close() { file_.close(); }

 private:
  friend void commit_rows(std::initializer_list<CsvFile*> files);

  void append_separator(bool& first) {
    if (!first) pending_.push_back(',');
    first = false;
  }
  template <std::integral T>
  void append_cell(T value) {
    static_assert(!std::same_as<T, bool>, "write a flag as 0 / 1");
    fmt::format_to(std::back_inserter(pending_), "{}", value);
  }
  // Floating-point cells are the recorder's largest formatting cost: std::to_chars gives
  // printf's text ("%.9g", "%.3f") without a locale, faster than fmt (bench_csv).
  template <std::floating_point T>
  void append_number(T value, std::chars_format format, int digits) {
    char text[128];
    const auto end = std::to_chars(text, text + sizeof text, value, format, digits);
    if (end.ec == std::errc()) {
      pending_.append(text, end.ptr);
    } else if (format == std::chars_format::fixed) {  // longer than 128 characters
      fmt::format_to(std::back_inserter(pending_), "{:.{}f}", value, digits);
    } else {
      fmt::format_to(std::back_inserter(pending_), "{:.{}g}", value, digits);
    }
  }
  template <std::floating_point T>
  void append_cell(T value) {
    append_number(value, std::chars_format::general, 9);
  }
  template <typename T>
  void append_cell(Sig<T> s) {
    append_number(s.value, std::chars_format::general, s.digits);
  }
  template <typename T>
  void append_cell(Fixed<T> f) {
    append_number(f.value, std::chars_format::fixed, f.digits);
  }
  void append_cell(std::string_view text);
  void append_cell(const std::string& text) { append_cell(std::string_view(text)); }
  void append_cell(const char* text) { append_cell(std::string_view(text)); }
  [[noreturn]] void wrong_arity(std::size_t cells) const;

  OutputFile file_;
  std::vector<std::string> columns_;
  fmt::memory_buffer pending_;
};

/// Writes the buffered rows of every file (null entries are skipped) as one unit: if a write
/// fails, every file is cut back to where it was before, the buffers are dropped and the
/// WriteError is rethrown. Files never end inside a row or hold half a frame.
void commit_rows(std::initializer_list<CsvFile*> files);

/// Disk space held back: a file of `bytes` allocated now and deleted by release(), so that what
/// must be written last (the summary saying why the run ended) still fits on a disk that filled
/// up. Released when destroyed.
class SpaceReserve {
 public:
  /// Throws WriteError if the space cannot be allocated.
  SpaceReserve(std::filesystem::path path, std::uint64_t bytes);
  ~SpaceReserve() { release(); }
  SpaceReserve(const SpaceReserve&) = delete;
  SpaceReserve& operator=(const SpaceReserve&) = delete;
  void release();

 private:
  std::filesystem::path path_;
  bool held_ = false;
};

/// Replaces `path` by a file holding `bytes`: written to a temporary file in the same
/// directory, synced, renamed over `path`, and the directory synced, so that once this returns
/// the new file survives a power loss (a rename is an entry of the directory: without the
/// directory's sync the old file, or none, may come back). Throws WriteError (and leaves `path`
/// as it was, or already replaced if only the directory's sync failed).
void write_file_atomically(const std::filesystem::path& path, std::string_view bytes);

/// Forces the entries of directory `dir` (files created, renamed or deleted in it) to the disk.
/// A file system that cannot sync a directory (EINVAL) is accepted as it is. Throws WriteError.
void sync_directory(const std::filesystem::path& dir);

/// Creates `dir` and its missing parents, each synced into its parent, so that a file later
/// published in `dir` with write_file_atomically survives a power loss with its directories.
/// Throws WriteError.
void create_directories_durably(const std::filesystem::path& dir);

}  // namespace syndds::record
