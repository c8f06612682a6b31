// The environment API on the double integrator: exact dynamics and episode ends, the same seed
// giving the same episode, and VectorEnv giving every copy the same episodes whatever the
// number of copies and threads (copy i's seeds depend on i only), with automatic resets.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "learn/double_integrator.hpp"
#include "learn/evaluate.hpp"
#include "learn/vector_env.hpp"

using namespace syndds::learn;

TEST(DoubleIntegrator, ConstantForceFromRestIsExact) {
  DoubleIntegrator env;
  env.reset(7);
  // x(t) = x0 + v0 t + a t^2 / 2 with a = 1 N on 1 kg.
  const double x0 = env.position(), v0 = env.velocity();
  const std::vector<float> push = {1.0f};
  for (int k = 1; k <= 10; ++k) {
    const StepResult r = env.step(push);
    const double t = 0.1 * k;
    EXPECT_NEAR(env.position(), x0 + v0 * t + 0.5 * t * t, 1e-12);
    EXPECT_NEAR(env.velocity(), v0 + t, 1e-12);
    EXPECT_FALSE(r.terminated);
    EXPECT_FALSE(r.truncated);
  }
  // Out of the box: clamped to 1 N.
  const std::vector<float> too_much = {5.0f};
  const double v = env.velocity();
  env.step(too_much);
  EXPECT_NEAR(env.velocity(), v + 0.1, 1e-12);
}

TEST(DoubleIntegrator, EpisodesEndAfterOneHundredStepsAndAreSeeded) {
  DoubleIntegrator a, b;
  const Observation oa = a.reset(42), ob = b.reset(42);
  EXPECT_EQ(oa.vector, ob.vector);
  EXPECT_NE(a.reset(43).vector, oa.vector);
  a.reset(42);
  const std::vector<float> act = {0.3f};
  for (int k = 1; k <= 100; ++k) {
    const StepResult ra = a.step(act), rb = b.step(act);
    EXPECT_EQ(ra.observation.vector, rb.observation.vector);
    EXPECT_EQ(ra.reward, rb.reward);
    EXPECT_EQ(ra.truncated, k == 100);
    EXPECT_FALSE(ra.terminated);
  }
  EXPECT_THROW(a.step(act), std::logic_error);
  DoubleIntegrator fresh;
  EXPECT_THROW(fresh.step(act), std::logic_error);
  fresh.reset(1);
  const std::vector<float> two = {0.1f, 0.2f};
  EXPECT_THROW(fresh.step(two), std::invalid_argument);
}

namespace {

// The first `steps` steps of copy `copy` in a VectorEnv of `copies` copies on `threads`
// threads, every copy pushed by a force that depends on its index and the step.
std::vector<float> trace(int copies, int threads, int copy, int steps) {
  VectorEnv env([] { return std::make_unique<DoubleIntegrator>(); }, copies, threads);
  std::vector<float> out;
  const auto first = env.reset(99);
  out.insert(out.end(), first[copy].vector.begin(), first[copy].vector.end());
  for (int k = 0; k < steps; ++k) {
    std::vector<std::vector<float>> actions;
    for (int i = 0; i < copies; ++i) actions.push_back({0.01f * static_cast<float>((i + k) % 7) - 0.03f});
    const VectorStepResult r = env.step(actions);
    const auto& o = r.results[copy].observation.vector;
    out.insert(out.end(), o.begin(), o.end());
    out.push_back(static_cast<float>(r.results[copy].reward));
  }
  return out;
}

}  // namespace

TEST(VectorEnv, CopyStreamsDoNotDependOnCopiesOrThreads) {
  const int steps = 250;  // two automatic resets
  const std::vector<float> reference = trace(1, 1, 0, steps);
  for (const int copies : {4, 8}) {
    for (const int threads : {1, 2}) {
      EXPECT_EQ(trace(copies, threads, 0, steps), reference) << copies << " " << threads;
    }
  }
  EXPECT_EQ(trace(4, 1, 3, steps), trace(8, 2, 3, steps));
  EXPECT_NE(trace(4, 1, 3, steps), trace(4, 1, 2, steps));
}

TEST(VectorEnv, AnEndedEpisodeIsResetWithTheNextEpisodeSeed) {
  VectorEnv env([] { return std::make_unique<DoubleIntegrator>(); }, 2, 2);
  env.reset(5);
  const std::vector<std::vector<float>> zero = {{0.0f}, {0.0f}};
  VectorStepResult r;
  for (int k = 0; k < 100; ++k) {
    r = env.step(zero);
    if (k < 99) {
      EXPECT_FALSE(r.final_observations[0].has_value());
    }
  }
  ASSERT_TRUE(r.final_observations[1].has_value());
  EXPECT_TRUE(r.results[1].truncated);
  DoubleIntegrator expected;
  EXPECT_EQ(r.results[1].observation.vector, expected.reset(episode_seed(5, 1, 1)).vector);
  EXPECT_NE(r.final_observations[1]->vector, r.results[1].observation.vector);
  EXPECT_THROW(env.step({{0.0f}}), std::invalid_argument);
  VectorEnv unused([] { return std::make_unique<DoubleIntegrator>(); }, 1, 1);
  EXPECT_THROW(unused.step({{0.0f}}), std::logic_error);
}

// Doing nothing: the mass drifts at its start velocity and every step costs x^2 + 0.1 v^2.
TEST(DoubleIntegrator, DoingNothingAccumulatesTheQuadraticCost) {
  DoubleIntegrator env;
  env.reset(3);
  const double v = env.velocity();
  double expected = 0.0, x = env.position();
  for (int k = 0; k < 100; ++k) {
    expected += -(x * x + 0.1 * v * v);
    x += v * 0.1;
  }
  double total = 0.0;
  const std::vector<float> none = {0.0f};
  for (int k = 0; k < 100; ++k) total += env.step(none).reward;
  EXPECT_NEAR(total, expected, 1e-9);
}

// evaluate(): episodes seeded first_seed, first_seed + 1, ...; the mean and spread of their
// returns; zero and random baselines.
namespace {

// The double integrator with an expert who asks for 0.5 on every other step and 0 between.
class HalfTaught final : public Env {
 public:
  ObservationSpace observation_space() const override { return env_.observation_space(); }
  Box action_space() const override { return env_.action_space(); }
  Observation reset(std::uint64_t seed) override {
    steps_ = 0;
    return env_.reset(seed);
  }
  StepResult step(std::span<const float> action) override {
    ++steps_;
    return env_.step(action);
  }
  std::vector<float> expert_action() const override { return {steps_ % 2 ? 0.5f : 0.0f}; }

 private:
  DoubleIntegrator env_;
  int steps_ = 0;
};

}  // namespace

// The distance to the teacher in the states the policy visits, per action: over every step
// and over the steps where the teacher's value is not 0; none without a teacher.
TEST(Evaluate, TheDistanceToTheTeacherPerAction) {
  HalfTaught env;
  const EvaluationSummary s = evaluate(env, zero_policy(env.action_space()), 40, 3);
  ASSERT_EQ(s.to_teacher.size(), 1u);
  const auto& t = s.to_teacher.at("force_n");
  EXPECT_NEAR(t.rms, std::sqrt(0.25 * 0.5), 1e-12);  // 0.5 on half of the 300 steps
  EXPECT_NEAR(t.active_rms, 0.5, 1e-12);
  EXPECT_EQ(t.active_steps, 150);
  DoubleIntegrator plain;
  EXPECT_TRUE(evaluate(plain, zero_policy(plain.action_space()), 40, 1).to_teacher.empty());
}

// The trace sees every step in order: the episode's seed, the step's index, the action, the
// teacher's action in the state the policy acted on, and what the step returned.
TEST(Evaluate, TheTraceSeesEveryStep) {
  HalfTaught env;
  std::vector<std::pair<std::uint64_t, int>> steps;
  double rewards = 0.0;
  int taught = 0;
  const EvaluationSummary s = evaluate(
      env, zero_policy(env.action_space()), 40, 2, 100000,
      [&](std::uint64_t seed, int step, const Observation& seen, const std::vector<float>& action,
          const std::vector<float>& teacher, const StepResult& r) {
        steps.emplace_back(seed, step);
        EXPECT_EQ(seen.vector.size(), 2u);
        EXPECT_EQ(action, std::vector<float>{0.0f});
        ASSERT_EQ(teacher.size(), 1u);
        EXPECT_EQ(teacher[0], step % 2 ? 0.5f : 0.0f);  // the expert before this step
        taught += teacher[0] != 0.0f ? 1 : 0;
        rewards += r.reward;
      });
  ASSERT_EQ(steps.size(), 200u);
  EXPECT_EQ(steps.front(), std::make_pair(std::uint64_t{40}, 0));
  EXPECT_EQ(steps[100], std::make_pair(std::uint64_t{41}, 0));
  EXPECT_EQ(steps.back(), std::make_pair(std::uint64_t{41}, 99));
  EXPECT_EQ(taught, 100);
  EXPECT_NEAR(rewards, s.episodes[0].total_reward + s.episodes[1].total_reward, 1e-9);
}

TEST(Evaluate, EpisodesWithConsecutiveSeedsAndTheirStatistics) {
  DoubleIntegrator env;
  const auto zero = zero_policy(env.action_space());
  const EvaluationSummary s = evaluate(env, zero, 40, 3);
  ASSERT_EQ(s.episodes.size(), 3u);
  double sum = 0.0, sum2 = 0.0;
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(s.episodes[k].seed, 40 + k);
    EXPECT_EQ(s.episodes[k].steps, 100);
    EXPECT_FALSE(s.episodes[k].terminated);
    // The same episode by hand.
    DoubleIntegrator again;
    again.reset(40 + k);
    double total = 0.0;
    for (int i = 0; i < 100; ++i) total += again.step(std::vector<float>{0.0f}).reward;
    EXPECT_EQ(s.episodes[k].total_reward, total);
    sum += total;
    sum2 += total * total;
  }
  EXPECT_NEAR(s.mean_return, sum / 3, 1e-9);
  EXPECT_NEAR(s.std_return, std::sqrt(sum2 / 3 - (sum / 3) * (sum / 3)), 1e-6);
  EXPECT_EQ(s.mean_steps, 100.0);
  EXPECT_EQ(s.terminated, 0);
  // Random actions stay in the box and depend only on their seed.
  const auto a = random_policy(env.action_space(), 5), b = random_policy(env.action_space(), 5);
  for (int i = 0; i < 100; ++i) {
    const auto x = a({}), y = b({});
    ASSERT_EQ(x, y);
    ASSERT_GE(x[0], -1.0f);
    ASSERT_LT(x[0], 1.0f);
  }
  EXPECT_THROW(evaluate(env, zero, 1, 0), std::invalid_argument);
}
