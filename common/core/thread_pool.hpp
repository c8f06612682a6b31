#pragma once
// One fixed set of worker threads for the data-parallel loops (SCM ray casting and soil law,
// camera tiles, lidar blocks). run(count, task) calls task(0) .. task(count - 1) exactly once
// each and returns when all are done; the calling thread takes part. Tasks are handed out
// through an atomic counter, so which thread runs which task varies from call to call: a caller
// that wants results independent of the thread count makes each task's output depend only on
// its index (and reduces outputs in index order afterwards). part_range() gives the fixed split
// of a range into a given number of parts for that purpose.
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace syndds {

class ThreadPool {
 public:
  /// `threads` >= 1 counts the calling thread (1: everything runs inline). Throws
  /// std::invalid_argument for threads < 1.
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  /// Threads that run tasks, the calling thread included.
  int size() const { return static_cast<int>(workers_.size()) + 1; }
  /// Runs task(0) .. task(count - 1) and returns when all are done. Not reentrant; task must
  /// not throw.
  void run(int count, const std::function<void(int)>& task);

 private:
  void work();
  void worker_loop();

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_;
  std::condition_variable done_;
  const std::function<void(int)>* task_ = nullptr;
  std::atomic<int> next_{0};
  int count_ = 0;
  int busy_ = 0;
  std::uint64_t generation_ = 0;
  bool stop_ = false;
};

/// Half-open range [begin, end) of part `part` when `count` items are split into `parts`
/// contiguous parts of (nearly) equal size.
inline std::pair<std::size_t, std::size_t> part_range(std::size_t count, int parts, int part) {
  const std::size_t p = static_cast<std::size_t>(parts);
  const std::size_t k = static_cast<std::size_t>(part);
  return {count * k / p, count * (k + 1) / p};
}

}  // namespace syndds
