#include <gtest/gtest.h>

#include <string>
#include <thread>

#include "core/cpu_policy.hpp"
#include "core/error.hpp"

using syndds::cpu_policy;
using syndds::set_cpu_policy;

// Run in a thread of its own: the policy is per thread, and the test runner's stays as it was.
TEST(CpuPolicy, BatchIsSetAndInheritedByThreadsCreatedAfterIt) {
  std::string own, child, back;
  std::thread t([&] {
    EXPECT_EQ(set_cpu_policy("batch"), "");
    own = cpu_policy();
    std::thread c([&] { child = cpu_policy(); });  // as Fast DDS's threads, made later
    c.join();
    EXPECT_EQ(set_cpu_policy("normal"), "");
    back = cpu_policy();
  });
  t.join();
  EXPECT_EQ(own, "batch");
  EXPECT_EQ(child, "batch");
  EXPECT_EQ(back, "normal");
}

TEST(CpuPolicy, AnUnknownPolicyNamesTheOption) {
  try {
    set_cpu_policy("fifo", "--cpu-policy");
    FAIL() << "no error";
  } catch (const syndds::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--cpu-policy 'fifo': expected batch or normal"),
              std::string::npos)
        << e.what();
  }
}
