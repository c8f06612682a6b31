#include "learn/double_integrator.hpp"

#include <algorithm>
#include <random>
#include <stdexcept>

namespace syndds::learn {
namespace {

// [0, 1) from 53 random bits: the same numbers on every standard library.
double unit(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

}  // namespace

ObservationSpace DoubleIntegrator::observation_space() const {
  return {Box{{-10.0f, -10.0f}, {10.0f, 10.0f}, {"position_m", "velocity_mps"}}, std::nullopt};
}

Box DoubleIntegrator::action_space() const { return Box{{-1.0f}, {1.0f}, {"force_n"}}; }

Observation DoubleIntegrator::reset(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  x_ = -2.0 + 4.0 * unit(rng);
  v_ = -0.5 + 1.0 * unit(rng);
  steps_ = 0;
  running_ = true;
  return observe();
}

StepResult DoubleIntegrator::step(std::span<const float> action) {
  if (!running_) throw std::logic_error("DoubleIntegrator::step before reset or after the end");
  if (action.size() != 1) throw std::invalid_argument("DoubleIntegrator: one action value");
  const double a = std::clamp(static_cast<double>(action[0]), -1.0, 1.0);
  const double dt = kPeriodS;
  StepResult r;
  r.reward = -(x_ * x_ + 0.1 * v_ * v_ + 0.01 * a * a);
  x_ += v_ * dt + 0.5 * a * dt * dt;
  v_ += a * dt;
  ++steps_;
  r.truncated = steps_ >= kSteps;
  running_ = !r.truncated;
  r.observation = observe();
  return r;
}

Observation DoubleIntegrator::observe() const {
  return {{static_cast<float>(x_), static_cast<float>(v_)}, {}};
}

}  // namespace syndds::learn
