// Environments by name (syndds_train --env, syndds.make in Python): the names, the convoy
// environment's options, and errors that name the environment, the option and the value.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "learn/registry.hpp"

using namespace syndds::learn;

namespace {

std::string error_of(const std::string& name, const EnvOptions& options) {
  try {
    env_factory(name, options);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Registry, KnowsEveryEnvironment) {
  EXPECT_EQ(env_names(), (std::vector<std::string>{"convoy_follow", "double_integrator"}));
  EXPECT_EQ(make_env("double_integrator")->action_space().size(), 1u);
  const auto convoy = make_env("convoy_follow");
  EXPECT_EQ(convoy->action_space().size(), 2u);
  EXPECT_EQ(convoy->observation_space().vector.size(), 4u);
  EXPECT_FALSE(convoy->observation_space().image.has_value());
}

TEST(Registry, ConvoyOptionsReachTheEnvironment) {
  const auto camera = make_env("convoy_follow", {{"camera", "true"}, {"terrain", "scm_soft"}});
  ASSERT_TRUE(camera->observation_space().image.has_value());
  EXPECT_EQ(camera->observation_space().image->width, 80);
  EXPECT_EQ(camera->observation_space().image->height, 45);
  // A step limit of 3: the third step truncates.
  const auto short_env = make_env("convoy_follow", {{"max_steps", "3"}, {"dynamics", "reduced"}});
  short_env->reset(1);
  const std::vector<float> brake = {0.0f, -1.0f};
  EXPECT_FALSE(short_env->step(brake).truncated);
  EXPECT_FALSE(short_env->step(brake).truncated);
  EXPECT_TRUE(short_env->step(brake).truncated);
  EXPECT_EQ(convoy_env_options({{"frames_per_step", "5"}}).frames_per_step, 5);
  EXPECT_EQ(convoy_env_options({}).frames_per_step, 10);
  EXPECT_EQ(convoy_env_options({{"chain", "0.5"}}).episode.chain_fraction, 0.5);
  EXPECT_EQ(convoy_env_options({}).episode.chain_fraction, 0.0);
  EXPECT_EQ(convoy_env_options({{"teacher_keep_clear", "2.5"}}).teacher_keep_clear_m, 2.5);
  EXPECT_EQ(convoy_env_options({}).teacher_keep_clear_m, 0.0);
  EXPECT_FALSE(convoy_env_options({}).teacher_view_camera);
  EXPECT_TRUE(convoy_env_options({{"teacher_view", "camera"}, {"camera", "true"}}).teacher_view_camera);
  const ConvoyEnvOptions ranges = convoy_env_options({{"teacher_view", "ranges"}, {"camera", "true"},
                                                      {"teacher_keep_clear", "2.5"},
                                                      {"observe_keep_out", "true"}});
  EXPECT_TRUE(ranges.teacher_view_ranges);
  EXPECT_FALSE(ranges.teacher_view_camera);
  EXPECT_TRUE(ranges.observe_keep_out);
  EXPECT_FALSE(convoy_env_options({}).observe_keep_out);
  EXPECT_EQ(convoy_env_options({{"observation", "trail_ff_memory"}}).observation,
            ConvoyObservationKind::trail_ff_memory);
  EXPECT_TRUE(convoy_env_options({{"ground_colour", "random"}}).random_ground_colour);
  EXPECT_FALSE(convoy_env_options({{"ground_colour", "fixed"}}).random_ground_colour);
  EXPECT_FALSE(convoy_env_options({}).random_ground_colour);
  EXPECT_EQ(convoy_env_options({{"friction_min", "0.45"}}).friction_min, 0.45);
  EXPECT_EQ(convoy_env_options({}).friction_min, 0.0);
  EXPECT_TRUE(convoy_env_options({{"steering", "residual"}, {"observation", "trail_ff"}})
                  .steering_residual);
  EXPECT_FALSE(convoy_env_options({}).steering_residual);
  EXPECT_EQ(convoy_env_options({{"start_hold_max", "8"}}).start_hold_max_s, 8.0);
  EXPECT_EQ(convoy_env_options({}).start_hold_max_s, 0.0);
}

TEST(Registry, MistakesAreNamed) {
  EXPECT_NE(error_of("cartpole", {}).find("unknown environment cartpole (known: convoy_follow, "
                                          "double_integrator)"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"terain", "rigid"}})
                .find("environment convoy_follow has no option terain"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"terrain", "sand"}})
                .find("option terrain: 'sand' is not one of rigid, scm_hard, scm_soft"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"camera", "yes"}}).find("option camera: 'yes'"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"target_speed", "fast"}})
                .find("option target_speed: 'fast' is not a number"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"target_speed", "50"}}).find("outside"), std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"frames_per_step", "2.5"}})
                .find("option frames_per_step: '2.5' is not a whole number"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"frames_per_step", "0"}}).find("outside"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"chain", "1.5"}}).find("option chain: '1.5' is outside"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"teacher_keep_clear", "-1"}})
                .find("option teacher_keep_clear: '-1' is outside"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"ground_colour", "pink"}})
                .find("option ground_colour: 'pink' is not one of fixed, random"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"ground_colour", "random"}, {"terrain", "scm_soft"}})
                .find("option ground_colour: random is for terrain=rigid"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"friction_min", "0.9"}})
                .find("option friction_min: '0.9' is outside"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"friction_min", "0.5"}, {"terrain", "scm_hard"}})
                .find("option friction_min: is for terrain=rigid"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"steering", "residual"}, {"observation", "trail"}})
                .find("option steering: residual needs an observation with the feed-forward"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"teacher_view", "camera"}})
                .find("option teacher_view: camera needs camera=true"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"teacher_view", "lidar"}})
                .find("option teacher_view: 'lidar' is not one of map, camera, ranges"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"teacher_view", "ranges"}})
                .find("option teacher_view: ranges needs camera=true"),
            std::string::npos);
  EXPECT_NE(error_of("convoy_follow", {{"observe_keep_out", "true"}})
                .find("option observe_keep_out: needs teacher_keep_clear > 0"),
            std::string::npos);
  EXPECT_NE(error_of("double_integrator", {{"mass", "2"}}).find("takes no options"),
            std::string::npos);
}
