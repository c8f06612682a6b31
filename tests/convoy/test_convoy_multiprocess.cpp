// A shipped convoy scenario with the real programs: one process per vehicle, follower and
// camera, V2V over DDS. Results must equal the single-process run byte for byte, the followers
// must stay in the convoy, and the chase camera's video must play.
#include <nlohmann/json.hpp>
#include <opencv2/videoio.hpp>

#include "harness.hpp"

using namespace syndds::test;

TEST(Convoy, OneLeaderThreeFollowersDistributedEqualsSingleProcess) {
  TestRun run;
  const std::string scenario = kConfig + "/scenarios/convoy/1L3F_rigid.yaml";
  const std::string single = single_process_csv(run, scenario, "");
  auto launcher = start_launcher(run, scenario);
  const auto code = launcher->wait(150.0);
  ASSERT_TRUE(code.has_value()) << "launcher still running";
  ASSERT_EQ(*code, 0) << launcher->log();
  const fs::path out = run.dir / "out";
  EXPECT_EQ(read_file(out / "vehicles.csv"), single);
  EXPECT_EQ(count_lines(single), 1u + 6001u * 4u);

  // The report: in convoy.json, summary.json and the launcher's end summary.
  const auto report = nlohmann::json::parse(read_file(out / "convoy.json"));
  ASSERT_EQ(report.size(), 3u);
  for (const auto& f : report) {
    SCOPED_TRACE(f.dump());
    EXPECT_EQ(f["leader_lost_events"], 0);
    EXPECT_EQ(f["obstacles_hit"], 0);
    EXPECT_LT(f["cross_track_m"]["mean"].get<double>(), 0.5);
    EXPECT_GT(f["time_gap_s"]["samples"].get<int>(), 1000);
  }
  const auto summary = nlohmann::json::parse(read_file(out / "summary.json"));
  EXPECT_EQ(summary["convoy"], report);
  EXPECT_NE(launcher->log().find("cross-track"), std::string::npos) << launcher->log();

  // The chase camera's video: as many frames as frames.csv lists, 320 x 180.
  const fs::path video = out / "sensors" / "f3" / "chase_camera.avi";
  cv::VideoCapture cap(video.string());
  ASSERT_TRUE(cap.isOpened()) << video;
  int frames = 0;
  cv::Mat image;
  while (cap.read(image)) {
    EXPECT_EQ(image.cols, 320);
    EXPECT_EQ(image.rows, 180);
    ++frames;
  }
  const auto listed = count_lines(read_file(out / "sensors" / "f3" / "frames.csv")) - 1;
  EXPECT_EQ(static_cast<std::size_t>(frames), listed);
  EXPECT_GE(frames, 15 * 60);  // 15 Hz for 60 s
}
