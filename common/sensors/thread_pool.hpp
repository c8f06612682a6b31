#pragma once
// A fixed set of worker threads that run numbered tasks (image tiles, lidar blocks). The
// caller takes part; tasks are handed out through an atomic counter, so which thread runs
// which task varies, but each task's output depends only on its index: results are identical
// for any thread count.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace syndds::sensors {

class ThreadPool {
 public:
  /// `threads` >= 1 counts the calling thread (1: everything runs inline).
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return static_cast<int>(workers_.size()) + 1; }
  /// Runs task(0) .. task(count - 1) and returns when all are done. Not reentrant.
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

}  // namespace syndds::sensors
