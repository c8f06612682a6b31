#pragma once
// Shared by the learning tests.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace syndds::test {

/// A fresh directory for one test case (ctest runs cases in parallel).
inline std::filesystem::path learn_test_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      (std::string("syndds-learn-") + info->test_suite_name() + "-" + info->name());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace syndds::test
