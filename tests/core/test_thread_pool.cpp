#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/thread_pool.hpp"

using syndds::part_range;
using syndds::ThreadPool;

TEST(ThreadPool, RejectsFewerThanOneThread) {
  EXPECT_THROW(ThreadPool(0), std::invalid_argument);
  EXPECT_THROW(ThreadPool(-3), std::invalid_argument);
}

TEST(ThreadPool, SizeCountsTheCallingThread) {
  EXPECT_EQ(ThreadPool(1).size(), 1);
  EXPECT_EQ(ThreadPool(3).size(), 3);
}

TEST(ThreadPool, RunsEveryTaskExactlyOnce) {
  for (const int threads : {1, 2, 3, 8}) {
    ThreadPool pool(threads);
    for (const int count : {0, 1, 2, 7, 1000}) {
      std::vector<std::atomic<int>> runs(static_cast<std::size_t>(count));
      pool.run(count, [&](int task) { runs[static_cast<std::size_t>(task)].fetch_add(1); });
      for (int t = 0; t < count; ++t) {
        EXPECT_EQ(runs[static_cast<std::size_t>(t)].load(), 1)
            << "threads " << threads << " count " << count << " task " << t;
      }
    }
  }
}

TEST(ThreadPool, OneThreadRunsInlineInOrder) {
  ThreadPool pool(1);
  std::vector<int> order;
  const auto caller = std::this_thread::get_id();
  bool elsewhere = false;
  pool.run(5, [&](int task) {
    order.push_back(task);
    elsewhere = elsewhere || std::this_thread::get_id() != caller;
  });
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_FALSE(elsewhere);
}

// Two tasks that each wait for the other to start can only finish if two threads run them.
TEST(ThreadPool, TasksRunConcurrently) {
  ThreadPool pool(2);
  std::atomic<int> started{0};
  std::atomic<bool> timed_out{false};
  pool.run(2, [&](int) {
    started.fetch_add(1);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (started.load() < 2) {
      if (std::chrono::steady_clock::now() > deadline) {
        timed_out = true;
        return;
      }
      std::this_thread::yield();
    }
  });
  EXPECT_FALSE(timed_out.load());
}

TEST(ThreadPool, ManyShortRunsInARow) {
  ThreadPool pool(3);
  std::atomic<long> sum{0};
  for (int r = 0; r < 2000; ++r) pool.run(4, [&](int task) { sum.fetch_add(task + 1); });
  EXPECT_EQ(sum.load(), 2000L * 10);
}

// The determinism recipe of the callers (SCM soil, camera, lidar): each task writes only its
// own slots, the caller reduces in index order. The sum must then be bit-identical for any
// thread count, although floating-point addition is not associative.
TEST(ThreadPool, IndexedOutputsReduceIdenticallyForAnyThreadCount) {
  constexpr std::size_t kItems = 100000;
  auto reduce = [&](int threads) {
    ThreadPool pool(threads);
    std::vector<double> out(kItems);
    const int parts = pool.size();
    pool.run(parts, [&](int part) {
      const auto [b, e] = part_range(kItems, parts, part);
      for (std::size_t k = b; k < e; ++k) out[k] = std::sin(0.001 * static_cast<double>(k)) / 3.0;
    });
    double sum = 0.0;
    for (const double x : out) sum += x;
    return sum;
  };
  const double one = reduce(1);
  for (const int threads : {2, 3, 5}) {
    const double many = reduce(threads);
    EXPECT_EQ(std::memcmp(&one, &many, sizeof one), 0) << threads << " threads";
  }
}

TEST(PartRange, SplitsIntoContiguousNearlyEqualParts) {
  for (const std::size_t count : {0u, 1u, 5u, 17u, 1000u}) {
    for (const int parts : {1, 2, 3, 7}) {
      std::size_t expect_begin = 0, smallest = count, largest = 0;
      for (int p = 0; p < parts; ++p) {
        const auto [b, e] = part_range(count, parts, p);
        EXPECT_EQ(b, expect_begin) << count << " / " << parts << " part " << p;
        EXPECT_LE(b, e);
        smallest = std::min(smallest, e - b);
        largest = std::max(largest, e - b);
        expect_begin = e;
      }
      EXPECT_EQ(expect_begin, count) << count << " / " << parts;
      EXPECT_LE(largest - smallest, 1u) << count << " / " << parts;
    }
  }
}
