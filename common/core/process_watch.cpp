#include "core/process_watch.hpp"

#include <unistd.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <vector>

namespace syndds {
namespace {

// Read once: it does not change while this process runs (a coordinator checks every member's
// key five times a second).
const std::string& boot_id() {
  static const std::string id = [] {
    std::ifstream in("/proc/sys/kernel/random/boot_id");
    std::string line;
    std::getline(in, line);
    return line;
  }();
  return id;
}

// The process's state letter and start time (clock ticks after boot) from /proc/PID/stat.
bool stat_of(int pid, char& state, std::string& start) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(in, line)) return false;
  const auto close = line.rfind(')');  // the command name may hold spaces and parentheses
  if (close == std::string::npos) return false;
  std::istringstream fields(line.substr(close + 1));
  std::string field;
  // Fields after the name: 3 state ... 22 starttime (proc(5)).
  for (int k = 3; k <= 22; ++k) {
    if (!(fields >> field)) return false;
    if (k == 3) state = field.empty() ? '?' : field[0];
  }
  start = field;
  return true;
}

}  // namespace

std::string process_key(int pid) {
  char state = '?';
  std::string start;
  const std::string& boot = boot_id();
  if (pid <= 0 || boot.empty() || !stat_of(pid, state, start)) return "";
  return boot + "/" + std::to_string(pid) + "/" + start;
}

std::string own_process_key() { return process_key(static_cast<int>(getpid())); }

bool process_running(const std::string& key) {
  const auto a = key.find('/');
  const auto b = key.rfind('/');
  if (a == std::string::npos || b == a) return false;
  int pid = 0;
  try {
    std::size_t used = 0;
    pid = std::stoi(key.substr(a + 1, b - a - 1), &used);
    if (used != b - a - 1) return false;
  } catch (const std::exception&) {
    return false;
  }
  char state = '?';
  std::string start;
  if (pid <= 0 || key.substr(0, a) != boot_id() || !stat_of(pid, state, start)) return false;
  return start == key.substr(b + 1) && state != 'Z' && state != 'X';
}

bool ProcessWatch::watch(const std::string& key, std::function<void()> on_exit) {
  if (!process_running(key)) return false;
  std::lock_guard lock(mutex_);
  if (stopping_) return false;
  watched_.emplace(key, std::move(on_exit));
  if (!thread_.joinable()) thread_ = std::thread([this] { loop(); });
  return true;
}

bool ProcessWatch::watching(const std::string& key) const {
  std::lock_guard lock(mutex_);
  return watched_.count(key) > 0;
}

void ProcessWatch::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    watched_.clear();
  }
  cv_.notify_all();
  if (thread_.joinable() && thread_.get_id() != std::this_thread::get_id()) thread_.join();
}

void ProcessWatch::loop() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    std::vector<std::function<void()>> exited;
    for (auto it = watched_.begin(); it != watched_.end();) {
      if (process_running(it->first)) {
        ++it;
      } else {
        exited.push_back(std::move(it->second));
        it = watched_.erase(it);
      }
    }
    if (!exited.empty()) {
      lock.unlock();
      for (auto& f : exited) f();
      lock.lock();
      continue;
    }
    cv_.wait_for(lock, std::chrono::duration<double>(poll_s_), [this] { return stopping_; });
  }
}

}  // namespace syndds
