#pragma once
// Perception fit: a camera network trained, by supervised regression, to read from the image
// alone what an environment's perception_target() says (for convoy_follow: the obstacles'
// ranges across the camera's view), on a fixed set of images collected while the
// environments' experts drive, and measured on episodes it never fitted before it drives
// anything (docs/learning.md, "Perception").
#include <torch/torch.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "learn/env.hpp"
#include "learn/ppo/networks.hpp"
#include "learn/ppo/perception_model.hpp"
#include "learn/vector_env.hpp"

namespace syndds::learn::ppo {

struct PerceptionOptions {
  std::int64_t steps = 0;  // interactions driven by the experts, summed over the copies
  int epochs = 10;
  int minibatch = 256;
  double holdout = 0.2;  // share of each copy's episodes measured, never fitted; in [0, 1)
  double learning_rate = 3e-4;
  double colour_jitter = 0.0;  // as CloneOptions::colour_jitter
  /// A target value below this counts as "something seen" (for the convoy ranges: an
  /// obstacle within range); the RMS over those values alone is reported as well, since most
  /// rays see nothing and a network that always says "nothing" scores well on all of them.
  double seen_below = 1.0;
};

struct PerceptionEpoch {
  int epoch = 0;  // 1-based
  double train_rms = 0.0;
  double holdout_rms = 0.0;       // NaN without held-out samples
  double holdout_seen_rms = 0.0;  // over held-out values < seen_below; NaN if none
};

struct PerceptionStats {
  std::int64_t train_samples = 0, holdout_samples = 0, episodes = 0;
  /// The held-out RMS of predicting each output's training mean (what an image-blind network
  /// scores), over all values and over the seen ones.
  double holdout_mean_rms = 0.0, holdout_mean_seen_rms = 0.0;
  double seen_share = 0.0;  // share of held-out values < seen_below
  std::vector<PerceptionEpoch> epochs;
  double collect_s = 0.0, learn_s = 0.0;  // wall times
};

/// Resets `envs` with `seed`, drives every copy by its expert_action() for `steps`
/// interactions (summed), keeping each observation's image and the environment's
/// perception_target() for it, then fits `net` (Adam, mean squared error, shuffled minibatches
/// drawn with `generator`). Every holdout-th share of each copy's episodes is held out.
/// Deterministic for fixed options and seed. std::invalid_argument when the environment has
/// no image, no expert or no perception target, a target's size is not the net's outputs, or
/// an option is out of range.
PerceptionStats fit_perception(VectorEnv& envs, std::uint64_t seed, const PerceptionOptions& options,
                               PerceptionNet& net, at::Generator& generator,
                               const std::function<void(const PerceptionEpoch&)>& progress = {});

}  // namespace syndds::learn::ppo
