#pragma once
// A small control task with a known good answer, for testing trainers: a unit mass on a line,
// pushed by a force in [-1, 1] N, to be brought to rest at the origin. State (x, v), control
// period 0.1 s (exact discretisation of constant force over the period), reward
// -(x^2 + 0.1 v^2 + 0.01 a^2) per step, 100 steps per episode (then truncated), start x uniform
// in [-2, 2] m, v uniform in [-0.5, 0.5] m/s. Doing nothing from rest at x = +-1 m scores
// exactly -100 per episode.
#include "learn/env.hpp"

namespace syndds::learn {

class DoubleIntegrator final : public Env {
 public:
  static constexpr double kPeriodS = 0.1;
  static constexpr int kSteps = 100;

  ObservationSpace observation_space() const override;
  Box action_space() const override;
  Observation reset(std::uint64_t seed) override;
  StepResult step(std::span<const float> action) override;

  double position() const { return x_; }
  double velocity() const { return v_; }

 private:
  Observation observe() const;
  double x_ = 0.0;
  double v_ = 0.0;
  int steps_ = 0;
  bool running_ = false;
};

}  // namespace syndds::learn
