// syndds_course: writes the scenario of one random obstacle course of the paper's statistical
// study (docs/ensemble.md): the field of --seed, the leader's planned path, the convoy.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "course/course.hpp"
#include "learn/policy_metadata.hpp"
#include "scenario/scenario.hpp"

using namespace syndds;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
  CLI::App app{"syndds course: write the scenario of a random obstacle course (docs/ensemble.md)"};
  std::uint64_t seed = 0;
  std::string terrain = "rigid";
  std::string convoy = "1L3F";
  std::string output;
  double target_mps = course::CourseOptions{}.target_speed_mps;
  std::string protocol = "current";
  app.add_option("--protocol", protocol,
                 "current: fields redrawn until a path keeps 2 m from the full-size obstacles, "
                 "ramp capped by --target-speed; paper: every field used, obstacles shrunk to "
                 "leave 2 m to the path, ramp not capped (docs/ensemble.md, \"Protocols\")")
      ->check(CLI::IsMember({"current", "paper"}))
      ->capture_default_str();
  app.add_option("--seed", seed, "Seed of the field and of the path planner")->required();
  app.add_option("--terrain", terrain, "Ground")
      ->check(CLI::IsMember({"rigid", "scm_hard", "scm_soft"}))
      ->capture_default_str();
  app.add_option("--convoy", convoy, "Leaders and followers")
      ->check(CLI::IsMember({"1L3F", "2L2F", "3L1F"}))
      ->capture_default_str();
  auto* target = app.add_option("--target-speed", target_mps,
                                "Cap of the leaders' speed ramp (m/s; current protocol)")
                     ->check(CLI::Range(0.5, 20.0))
                     ->capture_default_str();
  std::string follower_policy;
  app.add_option("--follower-policy", follower_policy,
                 "Followers driven by this learned policy (e.g. "
                 "policies/convoy_follow_lowdim.pt, under config/ or next to the scenario) "
                 "instead of the classical follower");
  std::string follower_rig;
  app.add_option("--follower-rig", follower_rig,
                 "The followers' sensor rig (config/sensors/<rig>.yaml; the chase video's "
                 "vehicle gets <rig>_chase). Default: with --follower-policy, the rig its "
                 "metadata names (<policy>.json, key sensors), else convoy");
  std::string follower_trail;
  app.add_option("--follower-trail", follower_trail,
                 "Whose trail the followers steer along: the vehicle each follows (leader) or "
                 "the convoy's head (head); their spacing is to the vehicle ahead either way. "
                 "Default: head for a learned follower (--follower-policy), leader for the "
                 "classical one")
      ->check(CLI::IsMember({"leader", "head"}));
  bool no_chase_video = false;
  app.add_flag("--no-chase-video", no_chase_video,
               "No chase camera and video behind the last vehicle (a study's runs need none: "
               "it takes most of a run's time and changes no metric)");
  app.add_option("--output", output, "Scenario file to write (.yaml)")->required();
  CLI11_PARSE(app, argc, argv);
  if (protocol == "paper" && target->count() > 0) {
    std::cerr << "syndds_course: --target-speed with --protocol paper: the paper's ramp has no "
                 "cap (use --protocol current for a capped ramp)\n";
    return 1;
  }
  try {
    const course::Course c = course::make_course(seed, course::parse_protocol(protocol));
    course::CourseOptions options;
    options.seed = seed;
    options.terrain = course::parse_terrain(terrain);
    options.convoy = convoy;
    options.target_speed_mps = target_mps;
    options.follower_policy = follower_policy;
    options.chase_video = !no_chase_video;
    options.follower_rig = follower_rig.empty() ? "convoy" : follower_rig;
    const std::string config_dir = scenario::default_config_dir();
    if (follower_rig.empty() && !follower_policy.empty()) {
      // The policy's file: under config/ or as given (next to the scenario, when the scenario
      // is written beside it).
      std::string file = (fs::path(config_dir) / follower_policy).string();
      if (!fs::exists(file)) file = follower_policy;
      if (const auto meta = learn::read_policy_sidecar(file)) {
        if (const auto it = meta->find("sensors"); it != meta->end()) options.follower_rig = it->second;
      }
    }
    // A learned follower learned behind one vehicle: in a convoy it steers along the head's
    // trail, so that what it gets wrong is not handed to the next (docs/convoy.md, step 8).
    options.follower_trail_head =
        follower_trail.empty() ? !follower_policy.empty() : follower_trail == "head";
    for (const std::string& rig :
         {options.follower_rig, options.chase_video ? options.follower_rig + "_chase" : ""}) {
      if (!rig.empty() && !fs::exists(fs::path(config_dir) / "sensors" / (rig + ".yaml"))) {
        std::cerr << "syndds_course: --follower-rig " << options.follower_rig << ": no rig "
                  << rig << " in " << config_dir << "/sensors\n";
        return 1;
      }
    }
    const std::string text = course::scenario_yaml(c, options);
    std::ofstream out(output, std::ios::binary);
    if (!out || !(out << text) || !out.flush()) {
      std::cerr << "syndds_course: cannot write --output " << output << "\n";
      return 1;
    }
    if (c.protocol == course::Protocol::paper) {
      const auto [shrunk, left_out] = course::count_scaled(c);
      std::printf(
          "%s: paper protocol, path %.1f m planned among the obstacles at %.1f of their "
          "radius, %d obstacles shrunk and %d left out to leave 2 m\n",
          output.c_str(), c.path.length_m, c.planning_scale, shrunk, left_out);
    } else {
      std::printf("%s: field draw %d, path %.1f m, clearance %.2f m\n", output.c_str(), c.draw,
                  c.path.length_m, c.path.clearance_m);
    }
  } catch (const std::exception& e) {
    std::cerr << "syndds_course: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
