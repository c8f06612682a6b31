// Benchmark (not a test): wall time of one PPO update (rollout, then GAE and the epochs of
// minibatches) with the trainer's defaults (1500 interactions, minibatch 64, 10 epochs, one
// copy, torch on one thread), for the MLP on the double integrator and for the sensor-fusion
// network on a stand-in environment with the paper's 80 x 45 camera image and a 4-vector
// (random pixels, 2 actions, 100-step episodes: the cost is the network's, not the task's).
//
//   bench_ppo [updates=5] [torch_threads=1] [minibatch=64]
//
// Prints per network the mean and the range over the updates after the first.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>

#include "learn/double_integrator.hpp"
#include "learn/ppo/trainer.hpp"

using namespace syndds::learn;

namespace {

class CameraStandIn final : public Env {
 public:
  ObservationSpace observation_space() const override {
    return {Box{std::vector<float>(4, -1.0f), std::vector<float>(4, 1.0f), {}},
            ImageSpec{80, 45, 3}};
  }
  Box action_space() const override { return Box{{-1.0f, -1.0f}, {1.0f, 1.0f}, {}}; }
  Observation reset(std::uint64_t seed) override {
    rng_.seed(seed);
    steps_ = 0;
    return observe();
  }
  StepResult step(std::span<const float> action) override {
    StepResult r;
    r.reward = -static_cast<double>(action[0] * action[0]);
    r.truncated = ++steps_ >= 100;
    r.observation = observe();
    return r;
  }

 private:
  Observation observe() {
    Observation o{std::vector<float>(4), std::vector<std::uint8_t>(80 * 45 * 3)};
    for (auto& v : o.vector) v = static_cast<float>(rng_() % 2001) / 1000.0f - 1.0f;
    for (auto& b : o.image) b = static_cast<std::uint8_t>(rng_() & 0xff);
    return o;
  }
  std::mt19937_64 rng_;
  int steps_ = 0;
};

void measure(const char* name, EnvFactory factory, int updates, int torch_threads,
             int minibatch) {
  ppo::TrainerOptions options;
  options.torch_threads = torch_threads;
  options.ppo.minibatch = minibatch;
  ppo::Trainer trainer(std::move(factory), options);
  double total = 0.0, lo = 1e30, hi = 0.0, rollout = 0.0, learn = 0.0;
  for (int u = 0; u < updates + 1; ++u) {
    const ppo::UpdateStats s = trainer.update();
    if (u == 0) continue;  // warm-up
    const double t = s.rollout_s + s.learn_s;
    total += t;
    rollout += s.rollout_s;
    learn += s.learn_s;
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  std::printf("%-7s %d interactions, minibatch %d, %d epochs, torch threads %d: update %.3f s "
              "(%.3f .. %.3f), rollout %.3f s, learning %.3f s\n",
              name, trainer.rollout_size(), options.ppo.minibatch, options.ppo.epochs,
              options.torch_threads,
              total / updates, lo, hi, rollout / updates, learn / updates);
}

}  // namespace

int main(int argc, char** argv) {
  const int updates = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
  const int threads = argc > 2 ? std::max(1, std::atoi(argv[2])) : 1;
  const int minibatch = argc > 3 ? std::max(2, std::atoi(argv[3])) : 64;
  measure("mlp", [] { return std::make_unique<DoubleIntegrator>(); }, updates, threads, minibatch);
  measure("fusion", [] { return std::make_unique<CameraStandIn>(); }, updates, threads, minibatch);
  return 0;
}
