#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "launch/launch_args.hpp"

namespace fs = std::filesystem;
using namespace syndds::launch;

namespace {

fs::path temp_dir(const char* name) {
  const fs::path d =
      fs::temp_directory_path() / ("syndds-launch-args-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

}  // namespace

TEST(LaunchArgs, TheScenarioComesFirstAndRunOptionsKeepTheirOrder) {
  const auto a = parse_launch_args(
      {"s.yaml", "--duration", "4.5", "--output", "o", "--realtime", "--domain", "7"});
  EXPECT_EQ(a.scenario, "s.yaml");
  EXPECT_EQ(a.output, "o");
  EXPECT_EQ(a.run.keys, (std::vector<std::string>{"--duration", "--realtime", "--domain"}));
  std::string layout;
  EXPECT_EQ(process_options(a, layout),
            (std::vector<std::string>{"--duration", "4.5", "--realtime", "--domain", "7"}));
  EXPECT_EQ(layout, "");
}

TEST(LaunchArgs, BadLinesAreNamed) {
  try {
    parse_launch_args({"s.yaml", "--frobnicate"});
    FAIL() << "accepted";
  } catch (const LaunchError& e) {
    EXPECT_STREQ(e.what(), "unknown option: --frobnicate (see --help)");
  }
  try {
    parse_launch_args({"s.yaml", "--duration"});
    FAIL() << "accepted";
  } catch (const LaunchError& e) {
    EXPECT_STREQ(e.what(), "--duration needs a value");
  }
  EXPECT_TRUE(parse_launch_args({"--help"}).help);
}

TEST(LaunchArgs, AResumeTakesTheRecordedRunUnlessTypedAgain) {
  const fs::path dir = temp_dir("resume");
  auto first = parse_launch_args({"s.yaml", "--duration", "4.5", "--processes", "per_vehicle",
                                  "--run-id", "r1", "--config-dir", "cfg"});
  write_launch_args(first, dir.string());
  auto again = parse_launch_args({"--resume", dir.string(), "--duration", "9"});
  merge_recorded(again);
  EXPECT_EQ(again.scenario, fs::absolute("s.yaml").string());
  EXPECT_EQ(again.run.get("--duration"), "9");  // typed now: wins
  EXPECT_EQ(again.run.get("--run-id"), "r1");
  EXPECT_EQ(again.run.get("--config-dir"), fs::absolute("cfg").lexically_normal().string());
  std::string layout;
  process_options(again, layout);
  EXPECT_EQ(layout, "per_vehicle");
  fs::remove_all(dir);
}

TEST(LaunchArgs, AResumeWithoutLaunchArgsNeedsTheScenario) {
  const fs::path dir = temp_dir("none");
  auto a = parse_launch_args({"--resume", dir.string()});
  EXPECT_THROW(merge_recorded(a), LaunchError);
  auto b = parse_launch_args({"s.yaml", "--resume", dir.string()});
  EXPECT_NO_THROW(merge_recorded(b));
  EXPECT_EQ(b.scenario, "s.yaml");
  std::ofstream(dir / "launch.args") << "s.yaml\n--output\nelsewhere\n";
  auto c = parse_launch_args({"--resume", dir.string()});
  EXPECT_THROW(merge_recorded(c), LaunchError);  // only run options are recorded
  fs::remove_all(dir);
}

TEST(LaunchArgs, AnArgumentWithALineBreakCannotBeRecorded) {
  const fs::path dir = temp_dir("newline");
  auto a = parse_launch_args({"s.yaml", "--run-id", "a\nb"});
  EXPECT_THROW(write_launch_args(a, dir.string()), LaunchError);
  EXPECT_FALSE(fs::exists(dir / "launch.args"));
  fs::remove_all(dir);
}
