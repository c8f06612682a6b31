#pragma once
// Helpers shared by the in-process DDS tests: participant options with the shipped QoS profiles,
// and a bounded wait on a condition (they count what arrives; they never sleep a fixed time).
#include <chrono>
#include <functional>
#include <string>
#include <thread>

#include "dds/participant.hpp"

namespace syndds::dds_test {

/// A participant on `domain` in run `run_id` (its partition), with config/dds/profiles.xml.
inline dds::DdsOptions options(int domain, const std::string& run_id) {
  dds::DdsOptions o;
  o.domain_id = domain;
  o.run_id = run_id;
  o.profiles_file = std::string(SYNDDS_TEST_CONFIG_DIR) + "/dds/profiles.xml";
  return o;
}

/// Polls `condition` every 10 ms for at most `limit_s`; true once it holds.
inline bool wait_until(const std::function<bool()>& condition, double limit_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(limit_s);
  while (!condition()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

}  // namespace syndds::dds_test
