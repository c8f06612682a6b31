#pragma once
// A small fixed pool of worker threads for the SCM ray casting. run(fn) calls fn(part) for
// part = 0 .. parts()-1, part 0 on the calling thread and part p on worker p, and returns when
// all are done. Work is split by the caller into a fixed partition, so results never depend on
// scheduling; the pool only decides *when* a part runs, not *what* it computes.
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace syndds::scm {

class WorkerPool {
 public:
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int parts() const { return static_cast<int>(workers_.size()) + 1; }
  /// Runs fn(0..parts()-1) and waits. fn must not throw.
  void run(const std::function<void(int)>& fn);

 private:
  void worker_loop(int part);

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_cv_;
  std::condition_variable done_cv_;
  const std::function<void(int)>* job_ = nullptr;
  std::uint64_t generation_ = 0;
  int pending_ = 0;
  bool stop_ = false;
};

/// Half-open range [begin, end) of part `part` when `count` items are split into `parts` parts.
inline std::pair<std::size_t, std::size_t> part_range(std::size_t count, int parts, int part) {
  const std::size_t p = static_cast<std::size_t>(parts);
  const std::size_t k = static_cast<std::size_t>(part);
  return {count * k / p, count * (k + 1) / p};
}

}  // namespace syndds::scm
