#include "core/config_files.hpp"

#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "core/hash.hpp"

namespace syndds {

std::string ConfigFiles::read(const std::string& path, const std::string& role) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path + ": cannot open file (" + role + ")");
  std::stringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) throw ConfigError(path + ": cannot read file (" + role + ")");
  std::string bytes = buffer.str();
  add(path, role, bytes);
  return bytes;
}

void ConfigFiles::add(const std::string& path, const std::string& role, std::string_view bytes) {
  files_.push_back({role, path, fnv1a64(bytes), static_cast<std::uint64_t>(bytes.size())});
}

std::uint64_t ConfigFiles::fingerprint() const {
  Fnv1a64 h;
  for (const auto& f : files_) {
    h.add(f.role);
    h.add(static_cast<std::int64_t>(f.hash));
    h.add(static_cast<std::int64_t>(f.size));
  }
  return h.value();
}

std::vector<std::string> fingerprint_lines(const std::vector<ConfigFile>& files) {
  std::vector<std::string> out;
  for (const auto& f : files) {
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(f.hash));
    out.push_back(f.role + " " + hex);
  }
  return out;
}

std::string describe(const std::vector<ConfigFile>& files) {
  std::string out;
  for (const auto& f : files) {
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(f.hash));
    out += (out.empty() ? "" : "\n") + f.role + " " + hex + " " + f.path;
  }
  return out;
}

}  // namespace syndds
