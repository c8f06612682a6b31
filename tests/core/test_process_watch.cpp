// Telling a running process from a dead one on this machine (core/process_watch.hpp): the key
// names one process (a reused pid is another key), and a watch calls back once when it exits.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "core/process_watch.hpp"

using namespace syndds;

namespace {

// A child that sleeps until killed; reaped by the caller.
pid_t sleeper() {
  const pid_t pid = fork();
  if (pid == 0) {
    pause();
    _exit(0);
  }
  return pid;
}

template <typename F>
bool eventually(F done, double limit_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(limit_s);
  while (!done()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

}  // namespace

TEST(ProcessWatch, KeysNameRunningProcessesOfThisMachineOnly) {
  const std::string own = own_process_key();
  ASSERT_FALSE(own.empty());
  EXPECT_TRUE(process_running(own));
  EXPECT_EQ(process_key(static_cast<int>(getpid())), own);

  const pid_t child = sleeper();
  const std::string key = process_key(child);
  ASSERT_FALSE(key.empty());
  EXPECT_TRUE(process_running(key));
  kill(child, SIGKILL);
  // Dead but not reaped yet (a zombie) is not running either.
  EXPECT_TRUE(eventually([&] { return !process_running(key); }, 10.0));
  waitpid(child, nullptr, 0);
  EXPECT_FALSE(process_running(key));

  // The same pid with another start time (a reused pid), another boot, garbage.
  const auto slash = own.rfind('/');
  EXPECT_FALSE(process_running(own.substr(0, slash) + "/1" + own.substr(slash + 1)));
  EXPECT_FALSE(process_running("00000000-0000-0000-0000-000000000000" + own.substr(own.find('/'))));
  for (const char* bad : {"", "x", "a/b/c", "//", "boot/-1/5"}) EXPECT_FALSE(process_running(bad));
  EXPECT_EQ(process_key(-1), "");
}

TEST(ProcessWatch, CallsBackOnceWhenAWatchedProcessExits) {
  const pid_t child = sleeper();
  const std::string key = process_key(child);
  std::atomic<int> calls{0};
  ProcessWatch watch(0.02);
  ASSERT_TRUE(watch.watch(key, [&] { ++calls; }));
  EXPECT_TRUE(watch.watching(key));
  EXPECT_TRUE(watch.watch(key, [&] { calls += 100; }));  // a second watch of it is ignored
  // Still running after several polls: no call.
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(calls.load(), 0);
  kill(child, SIGKILL);
  EXPECT_TRUE(eventually([&] { return calls.load() == 1; }, 10.0));
  waitpid(child, nullptr, 0);
  EXPECT_FALSE(watch.watching(key));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(calls.load(), 1);
  // A process that is not running cannot be watched.
  EXPECT_FALSE(watch.watch(key, [&] { ++calls; }));
  watch.stop();
  EXPECT_FALSE(watch.watch(own_process_key(), [&] { ++calls; }));
}
