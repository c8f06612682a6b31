// The learned-policy controller member against the environment it was trained in: the same
// episode driven by the environment (actions from Policy::act on its observations) and by a
// scenario whose follower has `controller: {type: policy}` (the agent builds the observation
// from its inputs and acts at the control period of its training) gives the same follower
// track bit for bit; a policy that does not fit the vehicle's sensors is refused naming the
// files.
#include <gtest/gtest.h>

#include <ATen/Parallel.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "agents/agent_factory.hpp"
#include "core/error.hpp"
#include "core/yaml.hpp"
#include "learn/convoy_env.hpp"
#include "learn/evaluate.hpp"
#include "learn/policy_controller.hpp"
#include "learn/policy_metadata.hpp"
#include "learn/registry.hpp"
#include "learn/ppo/trainer.hpp"
#include "protocol/local_runner.hpp"
#include "protocol/sample_state.hpp"
#include "record/checkpoint.hpp"
#include "scenario/scenario.hpp"
#include "learn_test_util.hpp"

namespace fs = std::filesystem;
using namespace syndds;
using namespace syndds::learn;

namespace {

// An untrained (randomly initialised) policy for the environment `options` describe: its
// actions are arbitrary but deterministic, which is all the comparison needs; the mean head's
// bias makes it drive (a little left, some throttle) rather than stand.
std::string write_policy(const fs::path& dir, const ConvoyEnvOptions& options) {
  fs::create_directories(dir);
  ppo::TrainerOptions t;
  t.seed = 3;
  ppo::Trainer trainer([options] { return make_convoy_env(options); }, t);
  {
    torch::NoGradGuard no_grad;
    bool found = false;
    for (auto& p : trainer.model().named_parameters()) {
      if (p.key() == "actor.4.bias" || p.key() == "mean.bias") {
        // A memory policy's memory is 0.3 at first: it comes back in its observation.
        p.value().copy_(has_memory(options.observation) ? torch::tensor({0.1f, 0.6f, 0.3f})
                                                        : torch::tensor({0.1f, 0.6f}));
        found = true;
      }
    }
    EXPECT_TRUE(found) << "no mean-head bias in the network";
  }
  const std::string path = (dir / "policy.pt").string();
  // As syndds_train writes it: the environment and its options (the observation's kind).
  PolicyMetadata meta{{"env", "convoy_follow"}, {"env_options", ""}};
  std::string env_options;
  if (options.observation == ConvoyObservationKind::trail) env_options = "observation=trail";
  if (options.observation == ConvoyObservationKind::trail_action) {
    env_options = "observation=trail_action";
  }
  if (options.observation == ConvoyObservationKind::trail_ff) env_options = "observation=trail_ff";
  if (options.observation == ConvoyObservationKind::trail_ff_memory) {
    env_options = "observation=trail_ff_memory";
  }
  if (options.steer_lag_s > 0.0) {
    env_options += (env_options.empty() ? "" : " ") + std::string("steer_lag=") +
                   std::to_string(options.steer_lag_s);
  }
  if (options.steering_residual) {
    env_options += (env_options.empty() ? "" : " ") + std::string("steering=residual");
  }
  if (options.observe_keep_out) {  // with the perception network it reads the ranges with
    env_options += " camera=true teacher_keep_clear=" + std::to_string(options.teacher_keep_clear_m) +
                   " teacher_view=ranges observe_keep_out=true";
    // Untrained, with its head made to see obstacles 6 m out on the left half of the view
    // (the image moves the readings a little around that).
    torch::manual_seed(5);
    ppo::PerceptionNet net(ImageSpec{80, 45, 3}, kPerceptionRays);
    {
      torch::NoGradGuard no_grad;
      for (auto& p : net.named_parameters()) {
        if (p.key() == "head.2.weight") p.value().mul_(0.01);
        if (p.key() == "head.2.bias") {
          for (int k = 0; k < kPerceptionRays; ++k) p.value()[k] = k < kPerceptionRays / 2 ? 0.3f : 1.5f;
        }
      }
    }
    ppo::PerceptionModel::save((dir / "perception.pt").string(), net, ImageSpec{80, 45, 3});
    meta["perception"] = "perception.pt";
  }
  if (options.frames_per_step != ConvoyEnvOptions{}.frames_per_step) {
    env_options += (env_options.empty() ? "" : " ") + std::string("frames_per_step=") +
                   std::to_string(options.frames_per_step);
  }
  meta["env_options"] = env_options;
  trainer.save_policy(path, meta);
  return path;
}

// The scenario of the environment's episode `seed` whose follower is driven by the policy
// controller (`extra`: more top-level keys).
scenario::Scenario policy_scenario(const ConvoyEnvOptions& options, std::uint64_t seed,
                                   const std::string& policy, const std::string& extra = "",
                                   const std::string& rig = "") {
  std::string yaml = convoy_scenario_yaml(make_convoy_episode(seed, options.episode),
                                          convoy_scenario_options(options, seed));
  if (!rig.empty()) {  // another rig for the follower (the leader's is `convoy`)
    const std::string camera = "    sensors: convoy_camera\n";
    yaml.replace(yaml.find(camera), camera.size(), "    sensors: " + rig + "\n");
  }
  const std::string external = "    controller: {type: external}\n";
  yaml.replace(yaml.find(external), external.size(),
               "    controller: {type: policy, follow: leader, model: " + policy + "}\n");
  yaml += extra;
  const std::string file = scenario::default_config_dir() + "/scenarios/convoy_env.yaml";
  return scenario::parse_scenario(YamlNode::load_string(yaml, file), yaml, {},
                                  scenario::default_config_dir());
}

// The follower's positions, frame by frame, in the scenario of the environment's episode
// `seed` whose follower is driven by the policy controller.
std::vector<proto::VehicleStateMsg> run_with_controller(const ConvoyEnvOptions& options,
                                                         std::uint64_t seed,
                                                         const std::string& policy,
                                                         std::int64_t frames,
                                                         const std::string& rig = "") {
  const auto s = policy_scenario(options, seed, policy, "", rig);
  proto::FrameStepper stepper(agents::make_all_agents(s, {}), s.time.heartbeat_s);
  std::vector<proto::VehicleStateMsg> track;
  for (std::int64_t f = 0; f < frames; ++f) {
    stepper.step();
    for (const auto& v : stepper.last_outputs().vehicle_states) {
      if (v.vehicle_id == kConvoyFollowerId) track.push_back(v);
    }
  }
  return track;
}

}  // namespace

// Environment options of a policy trained on observation `kind` with a steering lag.
static ConvoyEnvOptions trained_with(ConvoyObservationKind kind, double steer_lag_s = 0.0) {
  ConvoyEnvOptions options;
  options.observation = kind;
  options.steer_lag_s = steer_lag_s;
  return options;
}

static void drives_exactly_as_in_the_environment(ConvoyEnvOptions options,
                                                 const std::string& rig = "") {
  register_policy_controller();
  at::set_num_threads(1);
  const fs::path dir = syndds::test::learn_test_dir();
  const std::string policy_file = write_policy(dir, options);
  Policy policy;
  policy.load(policy_file);
  if (options.observe_keep_out) {  // the environment reads the ranges with the same network
    auto model = std::make_shared<ppo::PerceptionModel>(
        ppo::PerceptionModel::load((dir / "perception.pt").string()));
    options.perceive_ranges = [model](const Observation& o) { return model->read(o.image); };
  }
  double largest_shift = 0.0;

  // The environment: its own driver agent, the policy's deterministic actions; the follower's
  // state at the end of every step (frames from 0, as in a run).
  ConvoyEnv env(options);
  const std::uint64_t seed = 21;
  Observation obs = env.reset(seed);
  const std::vector<float> first_action = policy.act(obs, true);
  std::vector<proto::VehicleStateMsg> env_states = {env.follower_state()};
  // 2 s: this untrained policy runs into its leader soon after (a collision ends the episode).
  for (int k = 0; k < 20; ++k) {
    const StepResult r = env.step(policy.act(obs, true));
    obs = r.observation;
    env_states.push_back(env.follower_state());
    largest_shift = std::max(largest_shift, std::abs(env.teacher_shift_m()));
    ASSERT_FALSE(r.terminated || r.truncated)
        << "the episode ended early at step " << k << " (distance " << r.info.at("distance_m")
        << " m, collided " << r.info.at("collided") << ", leader_contact "
        << r.info.at("leader_contact") << "); pick another seed";
  }

  const auto track =
      run_with_controller(options, seed, policy_file, env_states.back().frame + 1, rig);
  ASSERT_EQ(track.size(), static_cast<std::size_t>(env_states.back().frame + 1));
  for (const auto& e : env_states) {
    const auto& t = track.at(static_cast<std::size_t>(e.frame));
    ASSERT_EQ(t.frame, e.frame);
    ASSERT_EQ(t.pose.position, e.pose.position) << "frame " << e.frame;
    ASSERT_EQ(t.pose.orientation.coeffs(), e.pose.orientation.coeffs()) << "frame " << e.frame;
    ASSERT_EQ(t.linear_velocity, e.linear_velocity) << "frame " << e.frame;
  }
  // The policy moved the follower (a track standing still would prove nothing).
  EXPECT_GT((track.back().pose.position - track.front().pose.position).norm(), 0.5);
  EXPECT_NE(first_action[0], 0.0f);
  // With a perceived keep-out the observation was shifted (else it would prove nothing).
  if (options.observe_keep_out) {
    std::printf("largest keep-out shift %.3f m\n", largest_shift);
    EXPECT_GT(largest_shift, 0.05);
  }
}

TEST(PolicyController, DrivesExactlyAsInTheEnvironment) {
  drives_exactly_as_in_the_environment(ConvoyEnvOptions{});
}

// A camera policy on a vehicle whose rig also films the chase video (convoy_camera_chase:
// the chase camera's 320 x 180 frames arrive too) observes only its front camera, as in
// training: the same track bit for bit.
TEST(PolicyController, ACameraPolicyObservesOnlyItsCameraBesideAChaseCamera) {
  ConvoyEnvOptions options;
  options.observation = ConvoyObservationKind::trail;
  options.camera = true;
  drives_exactly_as_in_the_environment(options, "convoy_camera_chase");
}

// The trail observation: the estimator inside the observation builder runs the same in the
// environment's driver agent and in the controller member.
TEST(PolicyController, DrivesExactlyAsInTheEnvironmentOnTheTrailObservation) {
  drives_exactly_as_in_the_environment(trained_with(ConvoyObservationKind::trail));
}

// trail_action: the previous action the observation holds is the one the controller applied,
// as in the environment.
TEST(PolicyController, DrivesExactlyAsInTheEnvironmentOnTheTrailActionObservation) {
  drives_exactly_as_in_the_environment(trained_with(ConvoyObservationKind::trail_action));
}

// trail_ff: the feed-forward steering (with the understeer the estimator learns while driving)
// is the same in the controller as in the environment.
TEST(PolicyController, DrivesExactlyAsInTheEnvironmentOnTheTrailFfObservation) {
  drives_exactly_as_in_the_environment(trained_with(ConvoyObservationKind::trail_ff));
}

// trail_ff_memory: the controller hands the policy's memory back in the next observation, as
// the environment does (the network's other outputs depend on it).
TEST(PolicyController, DrivesExactlyAsInTheEnvironmentOnTheMemoryObservation) {
  drives_exactly_as_in_the_environment(trained_with(ConvoyObservationKind::trail_ff_memory));
}

// A policy trained with a steering lag: the controller applies the same lag (from the policy's
// metadata), and its observation holds the lagged steering, as in the environment.
TEST(PolicyController, DrivesExactlyAsInTheEnvironmentWithASteeringLag) {
  drives_exactly_as_in_the_environment(trained_with(ConvoyObservationKind::trail_action, 0.25));
}

// A policy whose steering corrects the feed-forward (steering=residual): the controller adds
// the feed-forward of the observation the policy saw, as the environment does.
TEST(PolicyController, DrivesExactlyAsInTheEnvironmentWithResidualSteering) {
  ConvoyEnvOptions options = trained_with(ConvoyObservationKind::trail_ff);
  options.steering_residual = true;
  drives_exactly_as_in_the_environment(options);
}

// A policy that keeps clear of what its camera shows (observe_keep_out, teacher_view=ranges):
// the controller reads the ranges from the image the policy saw with the policy's perception
// network and gives them to the obstacle memory, as the environment does; the shift they
// make reaches the observation the same way.
static ConvoyEnvOptions keeping_clear_of_what_it_sees() {
  ConvoyEnvOptions options = trained_with(ConvoyObservationKind::trail_ff);
  options.camera = true;
  options.teacher_keep_clear_m = 2.5;
  options.teacher_view_ranges = true;
  options.observe_keep_out = true;
  return options;
}

TEST(PolicyController, DrivesExactlyAsInTheEnvironmentKeepingClearOfWhatItSees) {
  drives_exactly_as_in_the_environment(keeping_clear_of_what_it_sees());
}

// A policy trained at 20 Hz (frames_per_step 5): with no controller.period_s the controller
// acts at the policy's own period, as in the environment.
TEST(PolicyController, ActsAtThePeriodThePolicyWasTrainedWith) {
  ConvoyEnvOptions options = trained_with(ConvoyObservationKind::trail_ff);
  options.frames_per_step = 5;
  drives_exactly_as_in_the_environment(options);
}

// A period the scenario's heartbeat does not divide is refused naming the policy file.
TEST(PolicyController, APeriodTheHeartbeatDoesNotDivideIsRefused) {
  register_policy_controller();
  ConvoyEnvOptions options;
  options.frames_per_step = 5;
  const std::string policy_file = write_policy(syndds::test::learn_test_dir(), options);
  auto s = policy_scenario(options, 21, policy_file);
  s.time.heartbeat_s = 0.02;  // 0.05 s is 2.5 frames
  const auto follower = std::find_if(s.vehicles.begin(), s.vehicles.end(),
                                     [](const auto& v) { return v.id == kConvoyFollowerId; });
  ASSERT_NE(follower, s.vehicles.end());
  try {
    PolicyControllerAgent agent(s, *follower);
    FAIL() << "a 0.05 s policy on a 0.02 s heartbeat was accepted";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(policy_file), std::string::npos) << what;
    EXPECT_NE(what.find("not a whole multiple of time.heartbeat_s"), std::string::npos) << what;
  }
}

TEST(PolicyController, APolicyThatDoesNotFitTheSensorsIsRefused) {
  register_policy_controller();
  const fs::path dir = syndds::test::learn_test_dir();
  ConvoyEnvOptions camera;
  camera.camera = true;
  const std::string policy_file = write_policy(dir, camera);  // sees an image
  ConvoyEnvOptions low_dim;  // the vehicle has no camera
  try {
    run_with_controller(low_dim, 1, policy_file, 1);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("convoy_env.yaml: vehicle follower: controller.model " + policy_file),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("the policy observes 4 numbers and a 80 x 45 image, the vehicle's "
                        "sensors give 4 numbers"),
              std::string::npos)
        << what;
  }
  // The other way round is fine: a low-dimensional policy ignores the vehicle's cameras (a
  // chase camera filming the convoy, say).
  const std::string low_dim_file = write_policy(dir / "low", low_dim);
  EXPECT_NO_THROW(run_with_controller(camera, 1, low_dim_file, 5));
  // Not a policy file at all.
  std::ofstream(dir / "junk.pt") << "not a model";
  EXPECT_THROW(run_with_controller(low_dim, 1, (dir / "junk.pt").string(), 1), ConfigError);
}

// The policy shipped in config/policies (docs/learning.md: trained from scratch with
// syndds_train on convoy_follow, low-dimensional, rigid ground) on 10 episodes it never saw:
// far better than doing nothing or random actions, and about as good as the hand-written
// follower.
TEST(ShippedPolicy, BeatsTheBaselinesOnHeldOutEpisodes) {
  at::set_num_threads(1);
  Policy policy;
  policy.load(scenario::default_config_dir() + "/policies/convoy_follow_lowdim.pt");
  ConvoyEnv env;
  const std::uint64_t seeds = 1000000;
  const auto learned = evaluate(env, [&](const Observation& o) { return policy.act(o, true); },
                                seeds, 10);
  const auto zero = evaluate(env, zero_policy(env.action_space()), seeds, 10);
  const auto random = evaluate(env, random_policy(env.action_space(), 7), seeds, 10);
  const auto heuristic = evaluate(env, convoy_heuristic_action, seeds, 10);
  std::printf("mean return over 10 held-out episodes: learned %.1f, heuristic %.1f, zero %.1f, "
              "random %.1f\n",
              learned.mean_return, heuristic.mean_return, zero.mean_return, random.mean_return);
  EXPECT_GT(learned.mean_return, 2.5 * std::max(zero.mean_return, random.mean_return));
  EXPECT_GT(learned.mean_return, 0.8 * heuristic.mean_return);
  EXPECT_LE(learned.terminated, 3);  // at most 3 of 10 end in a collision or a lost leader
}

// The shipped camera policy (config/policies/convoy_follow_camera.pt, docs/learning.md:
// trail_ff observation, trained in two stages on rigid ground with imitation of the classical
// follower) in the environment its metadata names (full vehicle, camera), on 10 episodes of
// seeds it never saw: far better than doing nothing or random actions, and near the classical
// follower (the environment's expert, at the policy's 10 Hz) in return and in distance to the
// leader's path.
TEST(ShippedPolicy, CameraPolicyBeatsTheBaselinesOnHeldOutEpisodes) {
  at::set_num_threads(1);
  const std::string file = scenario::default_config_dir() + "/policies/convoy_follow_camera.pt";
  Policy policy;
  policy.load(file);
  ASSERT_TRUE(policy.observation_space().image.has_value());
  ASSERT_EQ(policy.metadata().at("sensors"), "convoy_camera");
  // The sidecar beside it says the same.
  const auto sidecar = read_policy_sidecar(file);
  ASSERT_TRUE(sidecar.has_value());
  EXPECT_EQ(*sidecar, policy.metadata());
  ConvoyEnvOptions options =
      convoy_env_options(parse_env_options_line(policy.metadata().at("env_options")));
  options.config_dir = scenario::default_config_dir();
  ConvoyEnv env(options);
  const std::uint64_t seeds = 2000000;  // training drew its episode seeds from episode_seed()
  const auto learned = evaluate(env, [&](const Observation& o) { return policy.act(o, true); },
                                seeds, 10);
  const auto classical =
      evaluate(env, [&](const Observation&) { return env.expert_action(); }, seeds, 10);
  const auto zero = evaluate(env, zero_policy(env.action_space()), seeds, 10);
  const auto random = evaluate(env, random_policy(env.action_space(), 7), seeds, 10);
  const double learned_error = learned.mean_info.at("path_error_m");
  const double classical_error = classical.mean_info.at("path_error_m");
  std::printf("camera policy, 10 held-out episodes: mean return learned %.1f (%d ended early), "
              "classical %.1f (%d), zero %.1f, random %.1f; mean path error learned %.3f m, "
              "classical %.3f m\n",
              learned.mean_return, learned.terminated, classical.mean_return,
              classical.terminated, zero.mean_return, random.mean_return, learned_error,
              classical_error);
  EXPECT_GT(learned.mean_return, 2.0 * std::max(zero.mean_return, random.mean_return));
  EXPECT_GT(learned.mean_return, 0.9 * classical.mean_return);
  EXPECT_LT(learned_error, 1.2 * classical_error);
  EXPECT_LE(learned.terminated, classical.terminated + 1);
}

// A run with a policy controller writes checkpoints, and a run resumed from one steps the same
// numbers as the run that wrote it: the policy's readings (the first frame after a checkpoint
// acts on them alone), its action and when the next one is due are in its state. Resumed from
// just before an action and from between two actions.
static void a_resumed_run_is_byte_identical(const ConvoyEnvOptions& options) {
  register_policy_controller();
  at::set_num_threads(1);
  const fs::path dir = syndds::test::learn_test_dir();
  const std::string policy_file = write_policy(dir, options);
  const auto s = policy_scenario(options, 21, policy_file, "checkpoint: {every_s: 1.5}\n");
  constexpr std::int64_t kEnd = 260;
  const auto controller = [](const proto::FrameStepper& st) -> const PolicyControllerAgent& {
    for (const auto& a : st.agents()) {
      if (const auto* p = dynamic_cast<const PolicyControllerAgent*>(a.get())) return *p;
    }
    throw std::logic_error("no policy controller");
  };
  // The frames after 150 in which the policy acts.
  std::vector<std::int64_t> acting;
  {
    proto::FrameStepper probe(agents::make_all_agents(s, {}), s.time.heartbeat_s);
    while (probe.next_frame() <= kEnd) {
      const auto before = controller(probe).actions_taken();
      probe.step();
      if (controller(probe).actions_taken() > before && probe.next_frame() - 1 > 150) {
        acting.push_back(probe.next_frame() - 1);
      }
    }
  }
  ASSERT_GE(acting.size(), 2u);
  const std::int64_t before_action = acting.front() - 1;  // the next frame acts
  const std::int64_t between = acting.front() + 4;        // 5 of the 10 frames to the next
  // Every frame's samples; checkpoints of `before_action` and `between` written into `run_dir`.
  const auto frames_of = [&](proto::FrameStepper& stepper, const fs::path& run_dir) {
    std::vector<std::string> frames;
    while (stepper.next_frame() <= kEnd) {
      stepper.step();
      core::StateWriter w;
      proto::save_samples(w, stepper.last_outputs());
      frames.push_back(w.take());
      const std::int64_t frame = stepper.next_frame() - 1;
      if (frame == before_action || frame == between) {
        record::write_local_checkpoint(run_dir, stepper, s.fingerprint, s.time.heartbeat_s);
      }
    }
    return frames;
  };
  auto agents = agents::make_all_agents(s, {});
  for (const auto& a : agents) EXPECT_NO_THROW(agents::require_checkpoints(s, *a));
  proto::FrameStepper straight(std::move(agents), s.time.heartbeat_s);
  const auto want = frames_of(straight, dir / "straight");
  ASSERT_EQ(want.size(), static_cast<std::size_t>(kEnd + 1));

  for (const std::int64_t from : {before_action, between}) {
    SCOPED_TRACE("resumed from the checkpoint of frame " + std::to_string(from));
    proto::FrameStepper resumed(agents::make_all_agents(s, {}), s.time.heartbeat_s);
    record::resume_local(dir / "straight", from, s.fingerprint, resumed);
    const auto got = frames_of(resumed, dir / ("resumed_" + std::to_string(from)));
    ASSERT_EQ(got.size(), static_cast<std::size_t>(kEnd - from));
    for (std::size_t i = 0; i < got.size(); ++i) {
      const std::size_t frame = static_cast<std::size_t>(from) + 1 + i;
      ASSERT_TRUE(got[i] == want[frame]) << "frame " << frame << " differs";
    }
    EXPECT_EQ(controller(resumed).actions_taken(), controller(straight).actions_taken());
  }
}

TEST(PolicyController, AResumedRunIsByteIdentical) { a_resumed_run_is_byte_identical({}); }

// The trail observation's estimator (filters, the leader's trail) is in the checkpoint too.
TEST(PolicyController, AResumedRunIsByteIdenticalOnTheTrailObservation) {
  a_resumed_run_is_byte_identical(trained_with(ConvoyObservationKind::trail));
}

// The previous action of the trail_action observation is in the checkpoint too.
TEST(PolicyController, AResumedRunIsByteIdenticalOnTheTrailActionObservation) {
  a_resumed_run_is_byte_identical(trained_with(ConvoyObservationKind::trail_action));
}

// The learned understeer behind trail_ff's feed-forward is in the estimator's checkpoint.
TEST(PolicyController, AResumedRunIsByteIdenticalOnTheTrailFfObservation) {
  a_resumed_run_is_byte_identical(trained_with(ConvoyObservationKind::trail_ff));
}

// The memory the policy last wrote is in the checkpoint too.
TEST(PolicyController, AResumedRunIsByteIdenticalOnTheMemoryObservation) {
  a_resumed_run_is_byte_identical(trained_with(ConvoyObservationKind::trail_ff_memory));
}

TEST(PolicyController, AResumedRunIsByteIdenticalWithASteeringLag) {
  a_resumed_run_is_byte_identical(trained_with(ConvoyObservationKind::trail_action, 0.25));
}

// The obstacle memory behind a perceived keep-out is in the checkpoint too.
TEST(PolicyController, AResumedRunIsByteIdenticalKeepingClearOfWhatItSees) {
  a_resumed_run_is_byte_identical(keeping_clear_of_what_it_sees());
}

// The residual sensor-fusion network started from a vector policy of an earlier stage acts
// exactly as that policy (its camera branch's heads start at zero), and learns from there:
// after one update the camera branch has changed and the actions differ.
TEST(ResidualFusion, StartsFromAVectorPolicyActingExactlyAsIt) {
  at::set_num_threads(1);
  const fs::path dir = syndds::test::learn_test_dir();
  ConvoyEnvOptions vector_options;
  vector_options.observation = ConvoyObservationKind::trail;
  const std::string vector_file = write_policy(dir / "vector", vector_options);
  ConvoyEnvOptions camera_options = vector_options;
  camera_options.camera = true;
  ppo::TrainerOptions t;
  t.seed = 4;
  t.network = "residual_fusion";
  t.ppo.steps_per_update = 64;
  t.ppo.epochs = 1;
  ppo::Trainer trainer([camera_options] { return make_convoy_env(camera_options); }, t);
  trainer.initialize_from_policy(vector_file);
  const std::string camera_file = (dir / "camera.pt").string();
  trainer.save_policy(camera_file);

  Policy vector_policy, camera_policy;
  vector_policy.load(vector_file);
  camera_policy.load(camera_file);
  ASSERT_TRUE(camera_policy.observation_space().image.has_value());
  ConvoyEnv env(camera_options);
  Observation obs = env.reset(31);
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(camera_policy.act(obs, true), vector_policy.act(obs, true)) << "step " << k;
    obs = env.step(camera_policy.act(obs, true)).observation;
  }
  trainer.update();
  trainer.save_policy(camera_file);
  camera_policy.load(camera_file);
  EXPECT_NE(camera_policy.act(obs, true), vector_policy.act(obs, true));
  // A camera network cannot start from a camera-less fusion file, nor a vector run from it.
  ppo::TrainerOptions plain;
  plain.network = "fusion";
  ppo::Trainer fusion([camera_options] { return make_convoy_env(camera_options); }, plain);
  EXPECT_THROW(fusion.initialize_from_policy(vector_file), std::invalid_argument);
}
