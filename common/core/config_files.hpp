#pragma once
// The files a configuration was read from. Every process of a run must load the same bytes
// (a host with another vehicle file, sensor rig, soil preset or height map would run other
// physics), so loaders read through ConfigFiles: it keeps each file's role (the key that named
// it, e.g. "vehicles[0].model"), path and content hash in read order, and the run's
// fingerprint is computed from the roles and hashes (not the paths: hosts may keep config/
// in different places).
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace syndds {

struct ConfigFile {
  std::string role;        // "scenario" or the key path that named the file
  std::string path;        // as opened on this host
  std::uint64_t hash = 0;  // FNV-1a 64 of the bytes
  std::uint64_t size = 0;  // bytes
};

class ConfigFiles {
 public:
  /// Reads a whole file and records it; ConfigError naming `path` (and the role) if it cannot.
  std::string read(const std::string& path, const std::string& role);
  /// Records bytes read elsewhere (or text given directly) under a role.
  void add(const std::string& path, const std::string& role, std::string_view bytes);
  const std::vector<ConfigFile>& files() const { return files_; }
  /// Hash of every (role, content hash, size) in read order.
  std::uint64_t fingerprint() const;

 private:
  std::vector<ConfigFile> files_;
};

/// "role hash" lines, one per file (hash as 16 hex digits): what a process announces, so that
/// a peer with another fingerprint can name the files that differ.
std::vector<std::string> fingerprint_lines(const std::vector<ConfigFile>& files);

/// "role path hash" lines, one per file, for logs and error messages.
std::string describe(const std::vector<ConfigFile>& files);

}  // namespace syndds
