// A shipped convoy scenario with the real programs: one process per vehicle, follower and
// camera, V2V over DDS. Results must equal the single-process run byte for byte, the followers
// must stay in the convoy, and the chase camera's video must play (and equal the single
// process's, byte for byte).
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
    EXPECT_GE(f["bumper_gap_m"]["min"].get<double>(), 2.0);
  }
  const auto summary = nlohmann::json::parse(read_file(out / "summary.json"));
  EXPECT_EQ(summary["convoy"], report);
  EXPECT_NE(launcher->log().find("cross m mean/max"), std::string::npos) << launcher->log();

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
  EXPECT_TRUE(read_file(video) ==
              read_file(run.dir / "single" / "sensors" / "f3" / "chase_camera.avi"));
}

// A participant that copies the controller's member id into commands of its own is refused:
// vehicles.csv equals the undisturbed single-process run, and every refused command is an
// event of the vehicle (events.csv, summary.json), never a row of commands.csv.
TEST(Intrusion, CommandsWithACopiedSourceAreRefusedAndRecorded) {
  TestRun run;
  const std::string scenario = kSource + "/tests/multiprocess/scenarios/two_vehicles.yaml";
  const std::string single = single_process_csv(run, scenario, "--duration 4");
  auto launcher = std::make_unique<Process>(
      "env SYNDDS_BUILD_DIR=" + kBin + "/.. " + kSource + "/launch_scripts/run_scenario.sh " +
          scenario + " --duration 4 --output " +
          (run.dir / "out").string() + run.common_args(),
      run.dir / "launcher.log");
  Process rogue(std::string(SYNDDS_ROGUE) + " --domain " + std::to_string(run.domain) +
                    " --run-id " + run.run_id + " --profiles " + kConfig +
                    "/dds/profiles.xml --vehicle a --source controller/a --seconds 60",
                run.dir / "rogue.log");
  const auto code = launcher->wait(90.0);
  ASSERT_TRUE(code.has_value());
  ASSERT_EQ(*code, 0) << launcher->log();
  ASSERT_TRUE(rogue.wait(20.0).has_value());
  const std::string rogue_log = rogue.log();
  const long written = std::stol(rogue_log.substr(rogue_log.find("wrote ") + 6));
  ASSERT_GT(written, 50) << rogue_log;  // it did try, in most frames

  const fs::path out = run.dir / "out";
  EXPECT_EQ(read_file(out / "vehicles.csv"), single);
  const std::string events = read_file(out / "events.csv");
  std::size_t refused = 0;
  for (std::size_t pos = events.find(",command_rejected,a,"); pos != std::string::npos;
       pos = events.find(",command_rejected,a,", pos + 1)) {
    ++refused;
  }
  EXPECT_GT(refused, 50u) << events.substr(0, 2000);
  EXPECT_NE(events.find("claimed controller/a"), std::string::npos);
  const auto summary = nlohmann::json::parse(read_file(out / "summary.json"));
  EXPECT_EQ(summary["vehicles"][0]["id"], "a");
  EXPECT_EQ(summary["vehicles"][0]["events"]["command_rejected"].get<std::size_t>(), refused);
  // No refused command reached the recorder: every row has the controller's own values.
  const std::string commands = read_file(out / "commands.csv");
  EXPECT_EQ(commands.find(",1,1,0,"), std::string::npos) << "a rogue command was recorded";
}
