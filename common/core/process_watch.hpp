#pragma once
// Is that process still running? A DDS participant whose lease expired may belong to a process
// that is only slow (a loaded machine, SIGSTOP, a debugger): on the same machine that can be
// told exactly, so overload is not taken for death (docs/protocol.md, "Failure handling").
#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>

namespace syndds {

/// "BOOT_ID/PID/START_TICKS": names one process of one boot of this machine (a reused pid or
/// another machine gives another key). Empty when /proc cannot tell.
std::string process_key(int pid);
std::string own_process_key();
/// True if `key` names a process of this machine that is running (not exited, not a zombie).
/// False for keys of other machines or boots, and for empty or malformed keys.
bool process_running(const std::string& key);

/// Calls a callback once when a watched process is no longer running (polled every
/// `poll_s`; one thread, started with the first watch). Callbacks run on that thread without
/// the watch's lock held; stop() (or the destructor) waits for a callback in progress.
class ProcessWatch {
 public:
  explicit ProcessWatch(double poll_s = 0.2) : poll_s_(poll_s) {}
  ~ProcessWatch() { stop(); }
  ProcessWatch(const ProcessWatch&) = delete;
  ProcessWatch& operator=(const ProcessWatch&) = delete;

  /// Watches `key` (a second watch of the same key is ignored); false if it is not running now.
  bool watch(const std::string& key, std::function<void()> on_exit);
  bool watching(const std::string& key) const;
  /// No more callbacks after this returns.
  void stop();

 private:
  void loop();

  const double poll_s_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::string, std::function<void()>> watched_;
  std::thread thread_;
  bool stopping_ = false;
};

}  // namespace syndds
