#include "launch/shm_ports.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <set>

namespace syndds::launch {
namespace fs = std::filesystem;

namespace {

constexpr int kPortBase = 7400;       // RTPS well-known ports: PB + DG * domain + ...
constexpr int kPortsPerDomain = 250;  // DG
constexpr const char* kPrefix = "fastrtps_port";

// Every path under `dir` that some process maps (its /proc/PID/maps names it).
std::set<std::string> mapped_under(const std::string& dir) {
  std::set<std::string> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/proc", ec)) {
    const std::string pid = e.path().filename().string();
    if (pid.empty() || !std::isdigit(static_cast<unsigned char>(pid[0]))) continue;
    std::ifstream maps(e.path() / "maps");
    std::string line;
    while (std::getline(maps, line)) {
      const auto at = line.find(dir);
      if (at == std::string::npos) continue;
      std::string path = line.substr(at);
      if (const auto del = path.find(" (deleted)"); del != std::string::npos) path.resize(del);
      out.insert(path);
    }
  }
  return out;
}

}  // namespace

std::vector<int> remove_stale_shm_ports(const std::string& dir, int domain, double min_age_s) {
  std::vector<int> removed;
  std::error_code ec;
  const fs::path root = fs::canonical(dir, ec);
  if (ec) return removed;
  const int first = kPortBase + kPortsPerDomain * domain;
  const auto mapped = mapped_under(root.string() + "/" + kPrefix);
  const auto now = std::chrono::system_clock::now();
  for (int port = first; port < first + kPortsPerDomain; ++port) {
    const std::string name = kPrefix + std::to_string(port);
    const fs::path file = root / name;
    struct stat st {};
    if (stat(file.c_str(), &st) != 0 || st.st_uid != getuid()) continue;
    if (mapped.count(file.string()) != 0) continue;
    const auto written = std::chrono::system_clock::from_time_t(st.st_mtim.tv_sec) +
                         std::chrono::nanoseconds(st.st_mtim.tv_nsec);
    if (std::chrono::duration<double>(now - written).count() < min_age_s) continue;
    for (const std::string& f : {name, name + "_el", name + "_sl", "sem." + name + "_mutex"}) {
      fs::remove(root / f, ec);
    }
    removed.push_back(port);
  }
  return removed;
}

}  // namespace syndds::launch
