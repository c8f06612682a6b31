// Convoy-follow environment throughput: environment steps (0.1 s of simulation each) per second
// of wall time, for the follower's reduced and full dynamics, with and without the camera, one
// copy on one thread and two copies on two threads (VectorEnv; automatic resets included),
// driven by a hand-written follower; and the time of one reset.
// Run: build/tests/benchmarks/bench_env [steps per copy, default 300]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "learn/convoy_env.hpp"
#include "learn/vector_env.hpp"

using namespace syndds::learn;
using Clock = std::chrono::steady_clock;

namespace {

// Steer toward the leader, throttle by the gap (as the tests' hand-written follower): episodes
// run their whole length, so resets are few.
std::vector<float> hand_policy(const Observation& o) {
  const double north = o.vector[0], east = o.vector[1];
  const double off = syndds::wrap_angle(std::atan2(east, north) - o.vector[2]);
  const double pedal = 0.15 * (std::hypot(north, east) - 15.0) - 0.3 * o.vector[3];
  return {static_cast<float>(std::clamp(-2.0 * off, -1.0, 1.0)),
          static_cast<float>(std::clamp(pedal, -1.0, 1.0))};
}

struct Result {
  double steps_per_s = 0.0;
  int episodes_ended = 0;
  double reset_ms = 0.0;  // one reset of one copy (scenario, agents, scene, first frames)
};

Result measure(ConvoyDynamics dynamics, bool camera, int copies, int steps) {
  ConvoyEnvOptions o;
  o.config_dir = SYNDDS_CONFIG_DIR;
  o.dynamics = dynamics;
  o.camera = camera;
  VectorEnv venv([&] { return make_convoy_env(o); }, copies, copies);
  Result r;
  const auto r0 = Clock::now();
  std::vector<Observation> obs = venv.reset(1);
  r.reset_ms = 1e3 * std::chrono::duration<double>(Clock::now() - r0).count() / copies;
  std::vector<std::vector<float>> actions(static_cast<std::size_t>(copies));
  const auto t0 = Clock::now();
  for (int k = 0; k < steps; ++k) {
    for (int i = 0; i < copies; ++i) {
      actions[static_cast<std::size_t>(i)] = hand_policy(obs[static_cast<std::size_t>(i)]);
    }
    auto out = venv.step(actions);
    for (int i = 0; i < copies; ++i) {
      auto& res = out.results[static_cast<std::size_t>(i)];
      r.episodes_ended += res.terminated || res.truncated ? 1 : 0;
      obs[static_cast<std::size_t>(i)] = std::move(res.observation);
    }
  }
  const double s = std::chrono::duration<double>(Clock::now() - t0).count();
  r.steps_per_s = copies * steps / s;
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  const int steps = argc > 1 ? std::atoi(argv[1]) : 300;
  std::printf("%-8s %-7s %-17s %10s %11s %9s %9s\n", "dynamics", "camera", "copies x threads",
              "steps/s", "x realtime", "episodes", "reset_ms");
  for (ConvoyDynamics d : {ConvoyDynamics::reduced, ConvoyDynamics::full}) {
    for (bool camera : {false, true}) {
      for (int copies : {1, 2}) {
        const Result r = measure(d, camera, copies, steps);
        std::printf("%-8s %-7s %-17s %10.0f %11.1f %9d %9.1f\n",
                    d == ConvoyDynamics::full ? "full" : "reduced", camera ? "yes" : "no",
                    copies == 1 ? "1 x 1" : "2 x 2", r.steps_per_s, r.steps_per_s * 0.1,
                    r.episodes_ended, r.reset_ms);
        std::fflush(stdout);
      }
    }
  }
  return 0;
}
