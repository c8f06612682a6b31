#pragma once
// Shared by the checkpoint-state tests: `fn` must throw core::StateError whose message holds
// every one of `parts`.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/state_io.hpp"

namespace syndds::test {

template <typename Fn>
void expect_state_error(Fn&& fn, const std::vector<std::string>& parts) {
  try {
    fn();
    ADD_FAILURE() << "no StateError";
  } catch (const core::StateError& e) {
    for (const auto& p : parts) {
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos)
          << "'" << p << "' not in: " << e.what();
    }
  }
}

}  // namespace syndds::test
