// The PPO trainer: GAE on a hand-computed rollout, the observation normaliser against known
// statistics, the networks' shapes, PPO solving the double integrator against a linear-quadratic
// regulator, bit-identical results across thread counts and across a checkpoint and resume, and
// the inference Policy.
#include <gtest/gtest.h>

#include <torch/torch.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "learn/double_integrator.hpp"
#include "learn/ppo/networks.hpp"
#include "learn/ppo/normalizer.hpp"
#include "learn/ppo/perception.hpp"
#include "learn/ppo/policy.hpp"
#include "learn/ppo/trainer.hpp"
#include "learn/registry.hpp"
#include "learn_test_util.hpp"

using namespace syndds::learn;
using namespace syndds::learn::ppo;
namespace fs = std::filesystem;

namespace {

EnvFactory double_integrator() {
  return [] { return std::make_unique<DoubleIntegrator>(); };
}

std::vector<torch::Tensor> parameters(Trainer& t) {
  std::vector<torch::Tensor> out;
  for (const auto& p : t.model().parameters()) out.push_back(p.detach().clone());
  return out;
}

void expect_identical(const std::vector<torch::Tensor>& a, const std::vector<torch::Tensor>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(torch::equal(a[i], b[i])) << "tensor " << i;
}

/// Mean return of `policy` over the double integrator's episodes of seeds 1000 .. 1000 + n - 1
/// (seeds training never uses: its episode seeds are hashes).
template <class F>
double mean_return(F policy, int episodes = 50) {
  double total = 0.0;
  for (int e = 0; e < episodes; ++e) {
    DoubleIntegrator env;
    Observation obs = env.reset(1000 + static_cast<std::uint64_t>(e));
    for (;;) {
      const std::vector<float> a = policy(obs);
      StepResult r = env.step(a);
      total += r.reward;
      if (r.terminated || r.truncated) break;
      obs = std::move(r.observation);
    }
  }
  return total / episodes;
}

/// The finite-horizon linear-quadratic regulator of the double integrator (gains for the 100
/// steps by the backward Riccati recursion), applied from step `step` on, clamped to [-1, 1].
struct Lqr {
  std::vector<std::array<double, 2>> gains;  // u = -(g0 x + g1 v)
  Lqr() {
    const double dt = DoubleIntegrator::kPeriodS;
    const double a[2][2] = {{1.0, dt}, {0.0, 1.0}};
    const double b[2] = {0.5 * dt * dt, dt};
    const double q[2] = {1.0, 0.1}, r = 0.01;
    double p[2][2] = {{0.0, 0.0}, {0.0, 0.0}};  // no terminal cost
    gains.resize(DoubleIntegrator::kSteps);
    for (int k = DoubleIntegrator::kSteps - 1; k >= 0; --k) {
      double pb[2] = {p[0][0] * b[0] + p[0][1] * b[1], p[1][0] * b[0] + p[1][1] * b[1]};
      const double s = r + b[0] * pb[0] + b[1] * pb[1];
      double bpa[2];  // B' P A
      for (int j = 0; j < 2; ++j) bpa[j] = pb[0] * a[0][j] + pb[1] * a[1][j];
      gains[static_cast<std::size_t>(k)] = {bpa[0] / s, bpa[1] / s};
      double pa[2][2];  // P A
      for (int i = 0; i < 2; ++i) {
        for (int j = 0; j < 2; ++j) pa[i][j] = p[i][0] * a[0][j] + p[i][1] * a[1][j];
      }
      double next[2][2];
      for (int i = 0; i < 2; ++i) {
        for (int j = 0; j < 2; ++j) {
          next[i][j] = (i == j ? q[i] : 0.0) + a[0][i] * pa[0][j] + a[1][i] * pa[1][j] -
                       bpa[i] * bpa[j] / s;
        }
      }
      std::copy(&next[0][0], &next[0][0] + 4, &p[0][0]);
    }
  }
};

double lqr_return() {
  const Lqr lqr;
  int step = 0;
  return mean_return([&](const Observation& o) {
    const auto& g = lqr.gains[static_cast<std::size_t>(step)];
    step = (step + 1) % DoubleIntegrator::kSteps;
    const double u = -(g[0] * o.vector[0] + g[1] * o.vector[1]);
    return std::vector<float>{static_cast<float>(std::clamp(u, -1.0, 1.0))};
  });
}

}  // namespace

TEST(Gae, HandComputedRolloutWithTerminationAndTruncation) {
  // Two copies, three steps, gamma 0.9, lambda 0.8; index t * 2 + k.
  // Copy 0: step 0 goes on, step 1 terminates (no value beyond), step 2 is truncated with a
  // final observation worth 4. Copy 1: no end; the value after the rollout is 2.
  const std::vector<double> rewards = {1, 1, 2, 1, 3, 1};
  const std::vector<double> values = {0.5, 0, 1.0, 0, 1.5, 0};
  const std::vector<double> next_values = {1.0, 0, 99.0 /* ignored */, 0, 4.0, 2.0};
  const std::vector<bool> terminated = {false, false, true, false, false, false};
  const std::vector<bool> truncated = {false, false, false, false, true, false};
  const Gae g = compute_gae(rewards, values, next_values, terminated, truncated, 3, 2, 0.9, 0.8);
  // Copy 0: delta2 = 3 + 0.9 * 4 - 1.5 = 5.1; delta1 = 2 - 1 = 1 (terminal);
  // A0 = (1 + 0.9 * 1 - 0.5) + 0.72 * A1 = 1.4 + 0.72 = 2.12 (A2 not carried over the end).
  EXPECT_NEAR(g.advantages[4], 5.1, 1e-12);
  EXPECT_NEAR(g.advantages[2], 1.0, 1e-12);
  EXPECT_NEAR(g.advantages[0], 2.12, 1e-12);
  EXPECT_NEAR(g.returns[4], 6.6, 1e-12);
  EXPECT_NEAR(g.returns[2], 2.0, 1e-12);
  EXPECT_NEAR(g.returns[0], 2.62, 1e-12);
  // Copy 1: A2 = 1 + 0.9 * 2 = 2.8, A1 = 1 + 0.72 * 2.8 = 3.016, A0 = 1 + 0.72 * 3.016.
  EXPECT_NEAR(g.advantages[5], 2.8, 1e-12);
  EXPECT_NEAR(g.advantages[3], 3.016, 1e-12);
  EXPECT_NEAR(g.advantages[1], 3.17152, 1e-12);
  EXPECT_THROW(compute_gae(rewards, values, next_values, terminated, truncated, 2, 2, 0.9, 0.8),
               std::invalid_argument);
}

TEST(RunningNormalizer, MatchesMeanAndVarianceOfAllDataSeen) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n0(5.0, 2.0), n1(-1.0, 0.1);
  std::vector<std::array<float, 2>> data;
  RunningNormalizer norm(2);
  for (int batch = 0; batch < 7; ++batch) {  // batches of 1 .. 7
    std::vector<std::array<float, 2>> b;
    for (int i = 0; i <= batch; ++i) {
      b.push_back({static_cast<float>(n0(rng)), static_cast<float>(n1(rng))});
    }
    std::vector<std::span<const float>> spans;
    for (const auto& x : b) spans.emplace_back(x);
    norm.update(spans);
    data.insert(data.end(), b.begin(), b.end());
  }
  ASSERT_EQ(norm.count(), 28.0);
  for (std::size_t j = 0; j < 2; ++j) {
    double mean = 0.0, var = 0.0;
    for (const auto& x : data) mean += x[j];
    mean /= static_cast<double>(data.size());
    for (const auto& x : data) var += (x[j] - mean) * (x[j] - mean);
    var /= static_cast<double>(data.size());
    EXPECT_NEAR(norm.mean()[j], mean, 1e-12);
    EXPECT_NEAR(norm.variance()[j], var, 1e-12);
  }
  const std::array<float, 2> at_mean = {static_cast<float>(norm.mean()[0]),
                                        static_cast<float>(norm.mean()[1] + std::sqrt(norm.variance()[1]))};
  const std::vector<float> z = norm.normalize(at_mean);
  EXPECT_NEAR(z[0], 0.0, 1e-5);
  EXPECT_NEAR(z[1], 1.0, 1e-4);
  const std::array<float, 2> far = {1e6f, -1e6f};
  EXPECT_EQ(norm.normalize(far), (std::vector<float>{10.0f, -10.0f}));
  const std::array<float, 3> wrong = {0, 0, 0};
  EXPECT_THROW(norm.normalize(wrong), std::invalid_argument);
}

TEST(Networks, MlpAndSensorFusionShapes) {
  torch::manual_seed(0);
  const Box actions{{-1, -1}, {1, 1}, {"steering", "throttle"}};
  ObservationSpace vec_only{Box{{0, 0, 0, 0}, {1, 1, 1, 1}, {}}, std::nullopt};
  const auto mlp = make_actor_critic("auto", vec_only, actions);
  EXPECT_EQ(mlp->kind(), "mlp");
  const ActorCriticOutput m = mlp->forward(torch::zeros({5, 4}), {});
  EXPECT_EQ(m.mean.sizes(), (std::vector<std::int64_t>{5, 2}));
  EXPECT_EQ(m.value.sizes(), (std::vector<std::int64_t>{5}));
  EXPECT_EQ(mlp->log_std.sizes(), (std::vector<std::int64_t>{2}));
  // 2 x (4*64 + 64 + 64*64 + 64) + (64*2 + 2) + (64 + 1) + 2 log-std.
  std::int64_t count = 0;
  for (const auto& p : mlp->parameters()) count += p.numel();
  EXPECT_EQ(count, 2 * (4 * 64 + 64 + 64 * 64 + 64) + 64 * 2 + 2 + 64 + 1 + 2);

  ObservationSpace camera = vec_only;
  camera.image = ImageSpec{80, 45, 3};
  const auto net = make_actor_critic("auto", camera, actions);
  ASSERT_EQ(net->kind(), "fusion");
  // 45 x 80 -> 10 x 19 (8/4) -> 4 x 8 (4/2) -> 2 x 6 (3/1), 64 filters.
  EXPECT_EQ(dynamic_cast<FusionActorCritic&>(*net).cnn_features(), 64 * 2 * 6);
  const torch::Tensor images = torch::randint(0, 256, {3, 45, 80, 3}).to(torch::kUInt8);
  const ActorCriticOutput f = net->forward(torch::zeros({3, 4}), images);
  EXPECT_EQ(f.mean.sizes(), (std::vector<std::int64_t>{3, 2}));
  EXPECT_EQ(f.value.sizes(), (std::vector<std::int64_t>{3}));
  EXPECT_THROW(make_actor_critic("fusion", vec_only, actions), std::invalid_argument);
  EXPECT_THROW(make_actor_critic("transformer", vec_only, actions), std::invalid_argument);
}

namespace {

/// The trainer's defaults on the double integrator with `copies` copies on `threads` threads.
TrainerOptions small_options(int copies, int threads, int steps_per_update) {
  TrainerOptions o;
  o.copies = copies;
  o.threads = threads;
  o.seed = 11;
  o.ppo.steps_per_update = steps_per_update;
  return o;
}

}  // namespace

TEST(Ppo, SolvesTheDoubleIntegratorNearTheRegulator) {
  // References over the 50 evaluation episodes: the regulator, doing nothing, uniform random
  // forces.
  const double lqr = lqr_return();
  const double nothing = mean_return([](const Observation&) { return std::vector<float>{0.0f}; });
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> force(-1.0f, 1.0f);
  const double random = mean_return([&](const Observation&) { return std::vector<float>{force(rng)}; });
  std::printf("evaluation returns: regulator %.2f, nothing %.2f, random %.2f\n", lqr, nothing,
              random);
  EXPECT_GT(lqr, nothing);
  EXPECT_GT(nothing, random);

  // PPO with the defaults (1500 interactions per update, one copy), seed 0.
  TrainerOptions o;
  o.seed = 0;
  Trainer trainer(double_integrator(), o);
  constexpr int kUpdates = 100;
  UpdateStats last;
  for (int u = 0; u < kUpdates; ++u) last = trainer.update();
  const fs::path dir = syndds::test::learn_test_dir();
  trainer.save_policy((dir / "policy.pt").string());
  Policy policy;
  policy.load((dir / "policy.pt").string());
  const double ppo = mean_return([&](const Observation& obs) { return policy.act(obs, true); });
  std::printf("PPO after %d updates: training moving average %.2f, deterministic evaluation %.2f\n",
              kUpdates, last.moving_average_return, ppo);
  // "Solved": within 50 % of the regulator's (negative) return, where doing nothing is 28
  // times worse. Measured (libtorch 1.13, seed 0): regulator -18.45, PPO -23.74.
  EXPECT_GT(ppo, 1.5 * lqr);
  fs::remove_all(dir);
}

TEST(Ppo, SameParametersWhateverTheThreadsStepping) {
  Trainer one(double_integrator(), small_options(4, 1, 200));
  Trainer two(double_integrator(), small_options(4, 2, 200));
  for (int u = 0; u < 3; ++u) {
    const UpdateStats a = one.update(), b = two.update();
    EXPECT_EQ(a.policy_loss, b.policy_loss);
    EXPECT_EQ(a.value_loss, b.value_loss);
    EXPECT_EQ(a.episodes, b.episodes);
  }
  expect_identical(parameters(one), parameters(two));
  // ...and a different seed does change them (the comparison can fail).
  TrainerOptions other = small_options(4, 1, 200);
  other.seed = 12;
  Trainer three(double_integrator(), other);
  for (int u = 0; u < 3; ++u) three.update();
  EXPECT_FALSE(torch::equal(parameters(one).front(), parameters(three).front()));
}

TEST(Ppo, ResumingFromACheckpointGivesTheStraightRunBitForBit) {
  const fs::path dir = syndds::test::learn_test_dir();
  const std::string checkpoint = (dir / "checkpoint.pt").string();
  // 150 interactions per update on 2 copies: the checkpoint falls inside episodes, which the
  // resumed run replays.
  Trainer straight(double_integrator(), small_options(2, 1, 150));
  std::vector<UpdateStats> expected;
  for (int u = 0; u < 4; ++u) expected.push_back(straight.update());
  {
    Trainer first(double_integrator(), small_options(2, 1, 150));
    first.update();
    first.update();
    first.save_checkpoint(checkpoint);
  }
  Trainer resumed(double_integrator(), small_options(2, 1, 150));
  resumed.load_checkpoint(checkpoint);
  EXPECT_EQ(resumed.updates(), 2);
  EXPECT_EQ(resumed.interactions(), 300);
  for (int u = 2; u < 4; ++u) {
    const UpdateStats s = resumed.update();
    EXPECT_EQ(s.update, expected[static_cast<std::size_t>(u)].update);
    EXPECT_EQ(s.policy_loss, expected[static_cast<std::size_t>(u)].policy_loss);
    EXPECT_EQ(s.value_loss, expected[static_cast<std::size_t>(u)].value_loss);
  }
  expect_identical(parameters(straight), parameters(resumed));
  EXPECT_EQ(straight.normalizer().mean(), resumed.normalizer().mean());
  // A checkpoint of another configuration is refused.
  Trainer other(double_integrator(), small_options(3, 1, 150));
  EXPECT_THROW(other.load_checkpoint(checkpoint), std::invalid_argument);
  fs::remove_all(dir);
}

// The curriculum's switch: a new stage (another environment option, another seed) starts
// from the network and observation normaliser of the last stage's policy file.
TEST(Ppo, AStageStartsFromTheNetworkOfTheLastOne) {
  const fs::path dir = syndds::test::learn_test_dir();
  const std::string file = (dir / "stage1.pt").string();
  Trainer first(double_integrator(), small_options(2, 1, 150));
  first.update();
  first.update();
  first.save_policy(file);
  TrainerOptions o = small_options(1, 1, 150);
  o.seed = 12;  // another initialisation: equal only if the file's network was taken
  Trainer second(double_integrator(), o);
  second.initialize_from_policy(file);
  expect_identical(parameters(first), parameters(second));
  EXPECT_EQ(first.normalizer().mean(), second.normalizer().mean());
  EXPECT_EQ(second.updates(), 0);
  EXPECT_EQ(second.init_from(), "stage1.pt");
  second.update();  // and it trains on
  // Where it started is kept through a checkpoint (the resumed policy's metadata names it),
  // and a run that has updated does not start over from a file.
  const std::string checkpoint = (dir / "checkpoint.pt").string();
  second.save_checkpoint(checkpoint);
  Trainer resumed(double_integrator(), o);
  resumed.load_checkpoint(checkpoint);
  EXPECT_EQ(resumed.init_from(), "stage1.pt");
  EXPECT_THROW(resumed.initialize_from_policy(file), std::logic_error);
  EXPECT_EQ(Trainer(double_integrator(), o).init_from(), "");
  // A policy of another environment (4 numbers, 2 actions) does not fit.
  const std::string convoy = (dir / "convoy.pt").string();
  Trainer(env_factory("convoy_follow"), small_options(1, 1, 150)).save_policy(convoy);
  Trainer third(double_integrator(), small_options(1, 1, 150));
  EXPECT_THROW(third.initialize_from_policy(convoy), std::invalid_argument);
  fs::remove_all(dir);
}

// A missing file, or one that is not a policy, is an error naming the file, one line long
// (libtorch's own message carries a stack trace).
TEST(Policy, AFileThatIsNotAPolicyIsNamedInOneLine) {
  const fs::path dir = syndds::test::learn_test_dir();
  const std::string missing = (dir / "missing.pt").string(), text = (dir / "text.pt").string();
  std::ofstream(text) << "not a policy\n";
  for (const std::string& file : {missing, text}) {
    Policy policy;
    try {
      policy.load(file);
      ADD_FAILURE() << file << " loaded";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(file), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
  fs::remove_all(dir);
}

TEST(Policy, DeterministicActionIsRepeatableAndInTheBox) {
  const fs::path dir = syndds::test::learn_test_dir();
  TrainerOptions o = small_options(1, 1, 200);
  o.network = "mlp";
  Trainer trainer(double_integrator(), o);
  trainer.update();
  trainer.save_policy((dir / "policy.pt").string());
  Policy policy;
  policy.load((dir / "policy.pt").string());
  EXPECT_EQ(policy.action_space().low, std::vector<float>{-1.0f});
  EXPECT_EQ(policy.observation_space().vector.size(), 2u);
  const Observation near{{0.3f, -0.1f}, {}};
  const std::vector<float> a = policy.act(near, true);
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(policy.act(near, true), a);
  // The same as the trainer's network mean on the normalised observation.
  const std::vector<float> z = trainer.normalizer().normalize(near.vector);
  const float mean =
      trainer.model().forward(torch::tensor(z).reshape({1, 2}), {}).mean.item<float>();
  EXPECT_EQ(a[0], std::clamp(mean, -1.0f, 1.0f));
  // Far away the mean leaves the box; the action does not. Samples stay in the box too.
  for (const float x : {-1e3f, 1e3f}) {
    const Observation far{{x, 0.0f}, {}};
    const float d = policy.act(far, true)[0];
    EXPECT_GE(d, -1.0f);
    EXPECT_LE(d, 1.0f);
    for (int i = 0; i < 20; ++i) {
      const float s = policy.act(far, false)[0];
      EXPECT_GE(s, -1.0f);
      EXPECT_LE(s, 1.0f);
    }
  }
  EXPECT_THROW(policy.act(Observation{{1.0f}, {}}, true), std::invalid_argument);
  Policy empty;
  EXPECT_THROW(empty.act(near, true), std::logic_error);
  fs::remove_all(dir);
}

namespace {

// The double integrator with an expert: a proportional-derivative law, clamped.
class TaughtDoubleIntegrator final : public Env {
 public:
  static float expert(double x, double v) {
    return static_cast<float>(std::clamp(-(1.5 * x + 2.0 * v), -1.0, 1.0));
  }
  ObservationSpace observation_space() const override { return env_.observation_space(); }
  Box action_space() const override { return env_.action_space(); }
  Observation reset(std::uint64_t seed) override { return env_.reset(seed); }
  StepResult step(std::span<const float> action) override { return env_.step(action); }
  std::vector<float> expert_action() const override {
    return {expert(env_.position(), env_.velocity())};
  }

 private:
  DoubleIntegrator env_;
};

// Mean squared distance of the policy's mean action to the expert's over the evaluation
// episodes' first states.
double distance_to_expert(Trainer& trainer) {
  const fs::path dir = syndds::test::learn_test_dir();
  trainer.save_policy((dir / "policy.pt").string());
  Policy policy;
  policy.load((dir / "policy.pt").string());
  double sum = 0.0;
  for (std::uint64_t seed = 1000; seed < 1050; ++seed) {
    TaughtDoubleIntegrator env;
    const Observation obs = env.reset(seed);
    const float e = env.expert_action()[0];
    const float a = policy.act(obs, true)[0];
    sum += (a - e) * (a - e);
  }
  fs::remove_all(dir);
  return sum / 50.0;
}

}  // namespace

// Imitation: with the expert's loss the policy's mean action comes to the expert's, far closer
// than PPO alone gets in the same updates; the weight falls linearly over imitation_updates;
// an environment without an expert is refused.
TEST(Ppo, ImitationBringsThePolicyToTheExpert) {
  const auto factory = [] { return std::make_unique<TaughtDoubleIntegrator>(); };
  TrainerOptions o = small_options(2, 1, 400);
  Trainer plain(factory, o);
  o.imitation_weight = 2.0;
  o.imitation_updates = 20;
  Trainer taught(factory, o);
  const double before = distance_to_expert(taught);
  UpdateStats first, s;
  for (int u = 0; u < 10; ++u) {
    plain.update();
    s = taught.update();
    if (u == 0) first = s;
  }
  EXPECT_DOUBLE_EQ(first.imitation_weight, 2.0);
  EXPECT_DOUBLE_EQ(s.imitation_weight, 2.0 * (1.0 - 9.0 / 20.0));
  EXPECT_LT(s.imitation_loss, 0.5 * first.imitation_loss);
  const double after = distance_to_expert(taught), ppo = distance_to_expert(plain);
  std::printf("squared distance to the expert: before %.4f, imitation %.4f, PPO alone %.4f\n",
              before, after, ppo);
  EXPECT_LT(after, 0.1 * before);
  EXPECT_LT(after, 0.5 * ppo);
  EXPECT_TRUE(std::isnan(plain.update().imitation_loss));

  o.imitation_weight = 1.0;
  Trainer no_expert(double_integrator(), o);
  EXPECT_THROW(no_expert.update(), std::invalid_argument);
}

namespace {

// The double integrator with a second action that is not explored (Box::explore), recording
// every action it is given.
class DoubleIntegratorWithMemory final : public Env {
 public:
  explicit DoubleIntegratorWithMemory(std::vector<std::vector<float>>* seen) : seen_(seen) {}
  ObservationSpace observation_space() const override { return env_.observation_space(); }
  Box action_space() const override {
    Box b = env_.action_space();
    b.low.push_back(-1.0f);
    b.high.push_back(1.0f);
    b.names.push_back("memory");
    b.explore = {true, false};
    return b;
  }
  Observation reset(std::uint64_t seed) override { return env_.reset(seed); }
  StepResult step(std::span<const float> action) override {
    seen_->emplace_back(action.begin(), action.end());
    return env_.step(action.first(1));
  }

 private:
  DoubleIntegrator env_;
  std::vector<std::vector<float>>* seen_;
};

}  // namespace

// A dimension the action space does not explore is acted on as the policy's mean: in a fresh
// policy's rollout (log-std 0: noise of standard deviation 1 in the explored dimension, a mean
// head initialised near 0) it stays near 0 while the explored one spreads; the policy file
// keeps the flags, and a sampled action of the loaded policy has noise only where explored.
TEST(Ppo, ADimensionThatIsNotExploredIsActedOnAsTheMean) {
  std::vector<std::vector<float>> seen;  // the copy runs on this thread (threads = 1)
  TrainerOptions o = small_options(1, 1, 400);
  Trainer trainer([&seen] { return std::make_unique<DoubleIntegratorWithMemory>(&seen); }, o);
  trainer.update();
  ASSERT_GE(seen.size(), 400u);
  double sum2 = 0.0, memory_max = 0.0;
  for (const auto& a : seen) {
    sum2 += a[0] * a[0];
    memory_max = std::max(memory_max, std::abs(static_cast<double>(a[1])));
  }
  const double spread = std::sqrt(sum2 / static_cast<double>(seen.size()));
  std::printf("explored: RMS %.3f; not explored: largest %.4f\n", spread, memory_max);
  EXPECT_GT(spread, 0.5);
  EXPECT_LT(memory_max, 0.1);

  const fs::path dir = syndds::test::learn_test_dir();
  trainer.save_policy((dir / "policy.pt").string());
  Policy policy;
  policy.load((dir / "policy.pt").string());
  ASSERT_EQ(policy.action_space().explore, (std::vector<bool>{true, false}));
  policy.seed(5);
  DoubleIntegratorWithMemory env(&seen);
  const Observation obs = env.reset(7);
  const std::vector<float> mean = policy.act(obs, true);
  const std::vector<float> a = policy.act(obs, false), b = policy.act(obs, false);
  EXPECT_NE(a[0], b[0]);
  EXPECT_EQ(a[1], mean[1]);
  EXPECT_EQ(b[1], mean[1]);
  fs::remove_all(dir);
}

// A run with imitation resumes bit for bit (the expert's actions come back with the replayed
// episodes, the weight's schedule from the update count), and a checkpoint refuses a run with
// another imitation schedule, which would silently train otherwise.
TEST(Ppo, AnImitationRunResumesBitForBitAndOnlyWithItsSchedule) {
  const fs::path dir = syndds::test::learn_test_dir();
  const std::string checkpoint = (dir / "checkpoint.pt").string();
  const auto factory = [] { return std::make_unique<TaughtDoubleIntegrator>(); };
  TrainerOptions o = small_options(2, 1, 150);
  o.imitation_weight = 1.5;
  o.imitation_updates = 6;
  Trainer straight(factory, o);
  std::vector<UpdateStats> expected;
  for (int u = 0; u < 4; ++u) expected.push_back(straight.update());
  {
    Trainer first(factory, o);
    first.update();
    first.update();
    first.save_checkpoint(checkpoint);
  }
  Trainer resumed(factory, o);
  resumed.load_checkpoint(checkpoint);
  for (int u = 2; u < 4; ++u) {
    const UpdateStats s = resumed.update();
    const UpdateStats& e = expected[static_cast<std::size_t>(u)];
    EXPECT_EQ(s.imitation_weight, e.imitation_weight);
    EXPECT_EQ(s.imitation_loss, e.imitation_loss);
    EXPECT_EQ(s.policy_loss, e.policy_loss);
  }
  expect_identical(parameters(straight), parameters(resumed));
  for (const auto& [weight, over] : {std::pair{1.0, 6}, std::pair{1.5, 0}, std::pair{0.0, 0}}) {
    TrainerOptions other = o;
    other.imitation_weight = weight;
    other.imitation_updates = over;
    Trainer t(factory, other);
    try {
      t.load_checkpoint(checkpoint);
      ADD_FAILURE() << "a checkpoint of imitation 1.5 over 6 loaded into " << weight << " over "
                    << over;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("imitation weight 1.5 over 6 updates"),
                std::string::npos)
          << e.what();
    }
  }
  fs::remove_all(dir);
}

// Behaviour cloning: the experts drive, the policy's mean is fitted to their actions, and what
// the held-out episodes measure comes down far below a policy of 0 (which the held-out
// targets' own RMS is); the split follows the episodes; a clone is repeatable bit for bit, and
// a run checkpointed right after it resumes exactly as the straight run goes on.
TEST(Ppo, CloningFitsTheExpertAndMeasuresOnEpisodesItHoldsOut) {
  const auto factory = [] { return std::make_unique<TaughtDoubleIntegrator>(); };
  const TrainerOptions o = small_options(2, 1, 200);
  CloneOptions c;
  c.steps = 3000;
  c.epochs = 40;
  c.minibatch = 64;
  c.holdout = 0.2;
  Trainer cloned(factory, o);
  const double before = distance_to_expert(cloned);
  std::vector<CloneEpoch> seen;
  const CloneStats s = cloned.clone(c, [&](const CloneEpoch& e) { seen.push_back(e); });
  // 1500 steps per copy, 15 episodes of 100: episodes 4, 9 and 14 of each copy are held out.
  EXPECT_EQ(s.train_samples, 2400);
  EXPECT_EQ(s.holdout_samples, 600);
  EXPECT_EQ(s.episodes, 30);
  ASSERT_EQ(s.epochs.size(), 40u);
  ASSERT_EQ(seen.size(), 40u);
  EXPECT_EQ(seen.back().holdout_rms, s.epochs.back().holdout_rms);
  ASSERT_EQ(s.epochs.back().holdout_zero_rms.size(), 1u);
  const double zero = s.epochs.back().holdout_zero_rms[0];
  const double first = s.epochs.front().holdout_rms[0], last = s.epochs.back().holdout_rms[0];
  const double after = distance_to_expert(cloned);
  std::printf("held-out RMS: a policy of 0 %.4f, epoch 1 %.4f, epoch 40 %.4f; squared distance "
              "on fresh episodes %.4f before, %.4f after\n",
              zero, first, last, before, after);
  EXPECT_LT(last, 0.5 * first);
  EXPECT_LT(last, 0.2 * zero);
  EXPECT_LT(after, 0.05 * before);

  // Repeatable, and resumable right after cloning.
  const fs::path dir = syndds::test::learn_test_dir();
  const std::string checkpoint = (dir / "checkpoint.pt").string();
  Trainer again(factory, o);
  const CloneStats s2 = again.clone(c);
  EXPECT_EQ(s2.epochs.back().holdout_rms, s.epochs.back().holdout_rms);
  expect_identical(parameters(cloned), parameters(again));
  again.save_checkpoint(checkpoint);
  Trainer resumed(factory, o);
  resumed.load_checkpoint(checkpoint);
  const UpdateStats a = again.update(), b = resumed.update();
  EXPECT_EQ(a.policy_loss, b.policy_loss);
  expect_identical(parameters(again), parameters(resumed));
  fs::remove_all(dir);

  // Only before the first update, only with an expert, only with sound options.
  EXPECT_THROW(again.clone(c), std::logic_error);
  Trainer no_expert(double_integrator(), o);
  EXPECT_THROW(no_expert.clone(c), std::invalid_argument);
  CloneOptions bad = c;
  bad.holdout = 1.0;
  Trainer fresh(factory, o);
  EXPECT_THROW(fresh.clone(bad), std::invalid_argument);
}

namespace {

// The taught double integrator, recording for every step whether the action it was given was
// its expert's.
class WatchedDoubleIntegrator final : public Env {
 public:
  explicit WatchedDoubleIntegrator(std::vector<bool>* experts_given) : given_(experts_given) {}
  ObservationSpace observation_space() const override { return env_.observation_space(); }
  Box action_space() const override { return env_.action_space(); }
  Observation reset(std::uint64_t seed) override { return env_.reset(seed); }
  StepResult step(std::span<const float> action) override {
    given_->push_back(action[0] == env_.expert_action()[0]);
    return env_.step(action);
  }
  std::vector<float> expert_action() const override { return env_.expert_action(); }

 private:
  TaughtDoubleIntegrator env_;
  std::vector<bool>* given_;
};

}  // namespace

// DAgger's iterations: the first is driven by the expert, the later ones by the policy (whose
// actions are not the expert's), the data aggregates over the iterations and every fit is on
// all of it; the policy ends close to the expert.
TEST(Ppo, CloningIterationsAreDrivenByThePolicyAndFitOnEverything) {
  std::vector<bool> given;  // one copy, stepped on this thread
  TrainerOptions o = small_options(1, 1, 200);
  CloneOptions c;
  c.steps = 1000;
  c.epochs = 20;
  c.minibatch = 64;
  c.iterations = 3;
  Trainer trainer([&given] { return std::make_unique<WatchedDoubleIntegrator>(&given); }, o);
  const CloneStats s = trainer.clone(c);
  ASSERT_EQ(given.size(), 3000u);
  const auto expert_steps = [&](std::size_t from) {
    return std::count(given.begin() + static_cast<std::ptrdiff_t>(from),
                      given.begin() + static_cast<std::ptrdiff_t>(from + 1000), true);
  };
  EXPECT_EQ(expert_steps(0), 1000);
  EXPECT_LT(expert_steps(1000), 100);
  EXPECT_LT(expert_steps(2000), 100);
  EXPECT_EQ(s.train_samples + s.holdout_samples, 3000);
  EXPECT_EQ(s.episodes, 30);
  ASSERT_EQ(s.epochs.size(), 60u);
  EXPECT_EQ(s.epochs[20].iteration, 2);
  EXPECT_EQ(s.epochs[20].epoch, 1);
  const double last = s.epochs.back().holdout_rms[0];
  std::printf("held-out RMS after 3 iterations: %.4f (a policy of 0: %.4f)\n", last,
              s.epochs.back().holdout_zero_rms[0]);
  EXPECT_LT(last, 0.2 * s.epochs.back().holdout_zero_rms[0]);
  EXPECT_LT(distance_to_expert(trainer), 0.01);
}

namespace {

// Episodes of 20 steps whose every observation is a freshly drawn 40 x 36 image (what `paint`
// draws on black from the episode's generator) and the step over 20; one action, unused.
class DrawnImages : public Env {
 public:
  explicit DrawnImages(std::string action) : action_(std::move(action)) {}
  ObservationSpace observation_space() const override {
    return {Box{{0.0f}, {1.0f}, {"time"}}, ImageSpec{kWidth, kHeight, 3}};
  }
  Box action_space() const override { return Box{{-1.0f}, {1.0f}, {action_}}; }
  Observation reset(std::uint64_t seed) override {
    rng_.seed(seed);
    step_ = 0;
    return draw();
  }
  StepResult step(std::span<const float>) override {
    StepResult r;
    ++step_;
    r.observation = draw();
    r.truncated = step_ >= 20;
    return r;
  }

 protected:
  static constexpr int kWidth = 40, kHeight = 36;
  virtual void paint(std::mt19937_64& rng, std::vector<std::uint8_t>& image) = 0;

 private:
  Observation draw() {
    Observation o;
    o.vector = {static_cast<float>(step_) / 20.0f};
    o.image.assign(kWidth * kHeight * 3, 0);
    paint(rng_, o.image);
    return o;
  }
  std::string action_;
  std::mt19937_64 rng_;
  int step_ = 0;
};

// Grey screens: each image is one grey level, and the expert's action is that level mapped
// onto [-1, 1]: an expert that reads the images' brightness.
class GreyScreens final : public DrawnImages {
 public:
  GreyScreens() : DrawnImages("level") {}
  std::vector<float> expert_action() const override {
    return {static_cast<float>((level_ - 127.5) / 87.5)};
  }

 private:
  void paint(std::mt19937_64& rng, std::vector<std::uint8_t>& image) override {
    level_ = std::uniform_int_distribution<int>(40, 215)(rng);
    std::fill(image.begin(), image.end(), static_cast<std::uint8_t>(level_));
  }
  int level_ = 0;
};

}  // namespace

// Colour jitter changes the training images and nothing else: an expert that reads the
// images' brightness is learnt from the images as rendered and, with the brightness
// scrambled by the jitter, far less well on the held-out images (which are measured as
// rendered); a jittered clone is repeatable bit for bit; a jitter outside [0, 1) is refused.
TEST(Ppo, ColourJitterChangesOnlyTheImagesTheCloningFitsOn) {
  const auto factory = [] { return std::make_unique<GreyScreens>(); };
  const TrainerOptions o = small_options(1, 1, 200);
  CloneOptions c;
  c.steps = 1000;
  c.epochs = 15;
  c.minibatch = 64;
  Trainer plain(factory, o);
  const double plain_rms = plain.clone(c).epochs.back().holdout_rms.at(0);
  c.colour_jitter = 0.5;
  Trainer jittered(factory, o);
  const CloneStats s = jittered.clone(c);
  const double zero = s.epochs.back().holdout_zero_rms.at(0);
  const double jittered_rms = s.epochs.back().holdout_rms.at(0);
  std::printf("held-out RMS: a policy of 0 %.4f, as rendered %.4f, jittered %.4f\n", zero,
              plain_rms, jittered_rms);
  EXPECT_LT(plain_rms, 0.2 * zero);
  EXPECT_GT(jittered_rms, 2.0 * plain_rms);

  Trainer again(factory, o);
  again.clone(c);
  expect_identical(parameters(jittered), parameters(again));
  for (const double bad : {-0.1, 1.0}) {
    CloneOptions b = c;
    b.colour_jitter = bad;
    Trainer fresh(factory, o);
    EXPECT_THROW(fresh.clone(b), std::invalid_argument) << bad;
  }
}

namespace {

// Bars: each image is black with a white bar 4 pixels wide at a column drawn anew, and the
// perception target is the bar's column over the width: something only the image tells. The
// expert does nothing.
class Bars final : public DrawnImages {
 public:
  explicit Bars(bool with_target = true) : DrawnImages("nothing"), with_target_(with_target) {}
  std::vector<float> expert_action() const override { return {0.0f}; }
  std::vector<float> perception_target() const override {
    if (!with_target_) return {};
    return {static_cast<float>(column_) / 36.0f};
  }

 private:
  void paint(std::mt19937_64& rng, std::vector<std::uint8_t>& image) override {
    column_ = std::uniform_int_distribution<int>(0, 36)(rng);
    for (int row = 0; row < kHeight; ++row) {
      for (int col = column_; col < column_ + 4; ++col) {
        for (int ch = 0; ch < 3; ++ch) image[static_cast<std::size_t>((row * kWidth + col) * 3 + ch)] = 255;
      }
    }
  }
  bool with_target_;
  int column_ = 0;
};

}  // namespace

// The perception fit reads from the images what only they carry: on held-out episodes its
// error falls far below an image-blind network's (the training targets' mean); the held-out
// split follows the episodes; the fit is repeatable bit for bit; an environment without a
// perception target or an image, and options out of range, are refused.
TEST(Ppo, ThePerceptionFitReadsTheTargetFromTheImage) {
  const auto fit = [](const EnvFactory& factory, const PerceptionOptions& p) {
    torch::manual_seed(7);
    VectorEnv envs(factory, 2, 1);
    const auto image = envs.observation_space().image;
    PerceptionNet net(image ? *image : ImageSpec{40, 36, 3}, 1);
    at::Generator g = at::make_generator<at::CPUGeneratorImpl>(7);
    std::vector<PerceptionEpoch> seen;
    PerceptionStats s = fit_perception(envs, 11, p, net, g, [&](const PerceptionEpoch& e) {
      seen.push_back(e);
    });
    EXPECT_EQ(seen.size(), s.epochs.size());
    std::vector<torch::Tensor> params;
    for (const auto& t : net.parameters()) params.push_back(t.detach().clone());
    return std::pair{s, params};
  };
  PerceptionOptions p;
  p.steps = 2000;
  p.epochs = 12;
  p.minibatch = 64;
  p.holdout = 0.2;
  const EnvFactory bars = [] { return std::make_unique<Bars>(); };
  const auto [s, params] = fit(bars, p);
  // 1000 steps per copy, 50 episodes of 20: every fifth episode held out.
  EXPECT_EQ(s.train_samples, 1600);
  EXPECT_EQ(s.holdout_samples, 400);
  EXPECT_EQ(s.episodes, 100);
  ASSERT_EQ(s.epochs.size(), 12u);
  const double blind = s.holdout_mean_rms, last = s.epochs.back().holdout_rms;
  std::printf("held-out RMS: image-blind %.4f, epoch 1 %.4f, epoch 12 %.6f\n", blind,
              s.epochs.front().holdout_rms, last);
  EXPECT_GT(blind, 0.25);  // a uniform column over [0, 1]: 0.29
  EXPECT_LT(last, 0.2 * blind);
  // Every value is "seen" (below 1) but a bar at the right edge.
  EXPECT_GT(s.seen_share, 0.9);
  EXPECT_LT(s.epochs.back().holdout_seen_rms, 0.2 * s.holdout_mean_seen_rms);

  const auto [again, again_params] = fit(bars, p);
  EXPECT_EQ(again.epochs.back().holdout_rms, last);
  expect_identical(params, again_params);

  EXPECT_THROW(fit([] { return std::make_unique<Bars>(false); }, p), std::invalid_argument);
  EXPECT_THROW(fit(double_integrator(), p), std::invalid_argument);
  for (const double bad : {-0.1, 1.0}) {
    PerceptionOptions b = p;
    b.holdout = bad;
    EXPECT_THROW(fit(bars, b), std::invalid_argument) << bad;
  }
}
