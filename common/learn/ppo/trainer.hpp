#pragma once
// Proximal Policy Optimization (Schulman et al. 2017) over a VectorEnv, on libtorch, CPU.
//
// One update: the K copies step ceil(steps_per_update / K) times with actions sampled from the
// Gaussian policy (the environments clamp them to the box), then `epochs` passes over the
// rollout in shuffled minibatches of the clipped surrogate, the (optionally clipped) value loss
// and an entropy bonus, with Adam and a global gradient-norm clip. Advantages are GAE(gamma,
// lambda): a terminated episode has no value beyond its last step, a truncated one is
// bootstrapped from the value of its final observation (VectorEnv's final_observations).
// Observation vectors are normalised by a running mean / variance (normalizer.hpp).
//
// Deterministic: for fixed options the parameters after n updates are the same bit for bit,
// whatever `threads` (the environments' threads; torch runs on `torch_threads`, 1 by default,
// which is what bit-identical results need), and a run resumed from a checkpoint continues
// exactly as the run that wrote it.
#include <torch/torch.h>

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "learn/ppo/networks.hpp"
#include "learn/ppo/normalizer.hpp"
#include "learn/policy_metadata.hpp"
#include "learn/ppo/policy_file.hpp"
#include "learn/vector_env.hpp"

namespace syndds::learn::ppo {

struct PpoOptions {
  int steps_per_update = 1500;  // interactions per update, summed over the copies
  int epochs = 10;
  int minibatch = 64;
  double learning_rate = 3e-4;
  double adam_epsilon = 1e-5;
  double gamma = 0.99;
  double lambda = 0.95;
  double clip = 0.2;
  bool clip_value = false;  // value loss clipped around the rollout's values, with `clip`
  double value_coef = 0.5;
  double entropy_coef = 0.0;
  double max_grad_norm = 0.5;
  bool normalize_advantages = true;  // per minibatch
  // Rewards divided by the running standard deviation of the discounted return (per copy,
  // restarted at episode ends) for learning, and clipped to +-10; statistics stay unscaled.
  bool normalize_rewards = true;
};

struct TrainerOptions {
  PpoOptions ppo;
  int copies = 1;    // environment copies
  int threads = 1;   // threads stepping the copies
  int torch_threads = 1;
  std::uint64_t seed = 0;  // network initialisation, sampling, shuffling, episode seeds
  std::string network = "auto";  // mlp, fusion or auto (networks.hpp)
  int return_window = 20;        // episodes in the moving average of returns
  /// Imitation of the environments' expert_action() (a teacher, e.g. the classical convoy
  /// follower): the loss gains weight times the mean over the minibatch of the squared
  /// distance between the policy's mean action and the expert's, for the states the policy
  /// itself visits (as DAgger collects them). The weight falls linearly to 0 over
  /// `imitation_updates` updates (0: constant). 0: PPO alone.
  double imitation_weight = 0.0;
  int imitation_updates = 0;
};

/// What one update did. Returns are the environment's (unscaled) episode returns.
struct UpdateStats {
  int update = 0;                  // 1-based count of updates done
  std::int64_t interactions = 0;   // total so far, summed over the copies
  std::int64_t episodes = 0;       // episodes finished during this update
  double mean_return = 0.0;        // of those episodes; NaN when none finished
  double moving_average_return = 0.0;  // of the last return_window finished episodes; NaN before any
  double policy_loss = 0.0;        // means over the update's minibatches
  double value_loss = 0.0;
  double entropy = 0.0;
  double approx_kl = 0.0;          // mean of (r - 1) - log r, r the probability ratio
  double clip_fraction = 0.0;      // fraction of samples with |r - 1| > clip
  double imitation_loss = 0.0;     // mean squared distance to the expert's action (NaN when
                                   // not imitating)
  double imitation_weight = 0.0;   // the weight this update used
  double rollout_s = 0.0;          // wall time collecting the rollout (not deterministic)
  double learn_s = 0.0;            // wall time of GAE and the epochs of minibatches
};

/// GAE over a rollout of `steps` x `copies` (index t * copies + k). next_values[i] is the value
/// of the observation that followed step i in the same episode: the next step's value, the
/// bootstrap value after the rollout's last step, or, where the episode was truncated at i,
/// the value of its final observation; it is ignored where the episode terminated at i.
struct Gae {
  std::vector<double> advantages;
  std::vector<double> returns;  // advantages + values
};
Gae compute_gae(const std::vector<double>& rewards, const std::vector<double>& values,
                const std::vector<double>& next_values, const std::vector<bool>& terminated,
                const std::vector<bool>& truncated, int steps, int copies, double gamma,
                double lambda);

/// Behaviour cloning before PPO (Pomerleau 1989; the "BC pretraining" of imitation-learning
/// libraries), optionally with DAgger's iterations (Ross, Gordon and Bagnell 2011). Iteration
/// 1: the copies are driven by their environments' expert_action() for `steps` interactions
/// (summed over the copies); iterations 2.. : driven by the policy's mean action, each state
/// labelled with the expert's action (so that the policy learns in the states it reaches
/// itself, e.g. with its own memory in the observation). Each iteration resets the copies on
/// episodes of its own (clone_seed(seed) + iteration - 1; PPO's episodes stay those of a run
/// without cloning), then fits the policy's mean to the expert's actions of everything
/// collected so far by `epochs` passes of mean squared error in shuffled minibatches (Adam at
/// the PPO learning rate, an optimiser of its own). Every `holdout`-th share of each copy's
/// episodes is held out: never fitted, only measured. The observation normaliser takes in
/// every collected observation, and each fit normalises them all alike. With colour_jitter
/// j > 0 every image of every training minibatch is fitted with its colours changed (data
/// augmentation): each
/// channel scaled by a factor drawn uniformly from [1 - j, 1 + j], then an offset drawn
/// uniformly from [-128 j, 128 j] added to all channels, clamped to [0, 255]. The held-out
/// images and the policy's driving in later iterations see the images as rendered.
/// Deterministic for fixed options, as PPO is.
struct CloneOptions {
  std::int64_t steps = 0;  // per iteration
  int epochs = 10;         // per iteration
  int minibatch = 256;
  double holdout = 0.2;  // in [0, 1)
  int iterations = 1;
  double colour_jitter = 0.0;  // in [0, 1); 0: the images as rendered
};

/// One pass over the cloning data: RMS distance to the expert per action dimension.
struct CloneEpoch {
  int iteration = 0;  // 1-based
  int epoch = 0;      // 1-based, within the iteration
  std::vector<double> train_rms;
  std::vector<double> holdout_rms;  // empty without held-out episodes
  std::vector<double> holdout_zero_rms;  // the held-out expert actions' own RMS (a policy of 0)
};

struct CloneStats {
  std::int64_t train_samples = 0;  // in all iterations
  std::int64_t holdout_samples = 0;
  std::int64_t episodes = 0;  // episodes finished during the collection
  std::vector<CloneEpoch> epochs;
  double collect_s = 0.0;  // wall times (not deterministic)
  double learn_s = 0.0;
};

/// The seed the copies are reset with for cloning.
std::uint64_t clone_seed(std::uint64_t seed);

class Trainer {
 public:
  Trainer(EnvFactory factory, TrainerOptions options);

  /// Collects one rollout and updates the networks.
  UpdateStats update();

  /// Behaviour cloning (CloneOptions); only before the first update. `progress` is called after
  /// each epoch. Afterwards the copies are reset as at construction. std::logic_error after an
  /// update, std::invalid_argument if the environment has no expert or the options are out of
  /// range.
  CloneStats clone(const CloneOptions& clone,
                   const std::function<void(const CloneEpoch&)>& progress = {});

  int updates() const { return updates_; }
  std::int64_t interactions() const { return interactions_; }
  /// Interactions per update: steps_per_update rounded up to a multiple of the copies.
  int rollout_size() const { return steps_ * options_.copies; }
  const TrainerOptions& options() const { return options_; }
  ActorCritic& model() { return *model_; }
  const RunningNormalizer& normalizer() const { return normalizer_; }

  /// Everything a resumed run needs (written to `path`.tmp, then renamed over `path`).
  void save_checkpoint(const std::string& path) const;
  /// Continues the run that wrote `path`; this trainer must have the same options (copies,
  /// steps, seed, network: checked) and environment.
  void load_checkpoint(const std::string& path);
  /// The inference file Policy::load reads: network, normaliser, spaces, `metadata`.
  void save_policy(const std::string& path, const PolicyMetadata& metadata = {}) const;
  /// Starts this (fresh) run from the network and observation normaliser of a policy file of
  /// an earlier stage (the curriculum: reduced model first, then the full one); the optimiser,
  /// counters and return statistics start anew. std::invalid_argument if the network kind or
  /// the spaces differ, naming the file; std::logic_error once this run has updated (a
  /// resumed run keeps the network its checkpoint holds).
  void initialize_from_policy(const std::string& path);
  /// The file name (no directory) of the policy this run started from, kept in its
  /// checkpoints: empty for a run from a random initialisation (or a checkpoint written
  /// before the name was kept).
  const std::string& init_from() const { return init_from_; }

 private:
  torch::Tensor vector_tensor(const std::vector<const Observation*>& obs) const;
  torch::Tensor image_tensor(const std::vector<const Observation*>& obs) const;
  double scaled_reward(std::size_t copy, double reward, bool ended);

  TrainerOptions options_;
  VectorEnv envs_;
  ObservationSpace observation_space_;
  Box action_space_;
  torch::Tensor explored_;  // [A]: 1 where action_space_.explored(i), else 0
  std::shared_ptr<ActorCritic> model_;
  std::unique_ptr<torch::optim::Adam> optimizer_;
  RunningNormalizer normalizer_;
  RunningNormalizer return_normalizer_{1};
  std::vector<double> discounted_returns_;  // per copy, for return_normalizer_
  at::Generator generator_;
  int steps_ = 0;
  int updates_ = 0;
  std::string init_from_;
  std::int64_t interactions_ = 0;
  std::vector<Observation> observations_;                     // current, raw
  std::vector<std::vector<std::vector<float>>> episode_actions_;  // per copy, current episode
  std::vector<double> episode_returns_;                       // per copy, current episode
  std::deque<double> recent_returns_;                         // finished episodes, last window
};

}  // namespace syndds::learn::ppo
