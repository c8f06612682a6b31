// syndds_recorder: writes the run directory (CSV, JSON) frame by frame.
#include "common/member_main.hpp"

int main(int argc, char** argv) {
  std::string output = "runs/latest";
  return syndds::service::member_main(
      "recorder", "syndds recorder: writes every complete frame to the run directory", argc, argv,
      [&](CLI::App& app) {
        app.add_option("--output", output, "Run directory")->capture_default_str();
      },
      [&](const syndds::scenario::Scenario&) { return std::string(syndds::scenario::kRecorderMember); },
      &output);
}
