#pragma once
// A trained policy for inference (a controller driving with it): the file Trainer::save_policy
// writes (syndds_train's policy.pt) holds the network, the observation normaliser and the
// spaces. act() normalises the observation as in training and returns the Gaussian policy's
// mean (deterministic) or a sample, clamped to the action box either way.
#include <torch/torch.h>

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "learn/env.hpp"
#include "learn/policy_metadata.hpp"
#include "learn/ppo/networks.hpp"
#include "learn/ppo/normalizer.hpp"

namespace syndds::learn::ppo {

/// Writes the policy file of `model` (used by Trainer::save_policy).
void save_policy_file(const std::string& path, const ActorCritic& model,
                      const RunningNormalizer& normalizer, const ObservationSpace& observations,
                      const Box& actions, const PolicyMetadata& metadata = {});

/// The tensor stored under `key`, read into a fresh tensor (reading into a defined one copies
/// into its storage, which fails when the sizes differ). Throws when the key is missing.
torch::Tensor read_tensor(torch::serialize::InputArchive& archive, const std::string& key);

}  // namespace syndds::learn::ppo

namespace syndds::learn {

class Policy {
 public:
  /// Reads a policy file; throws std::runtime_error (c10::Error) for a file that is not one.
  void load(const std::string& path);
  /// The action for one observation (the observation space's sizes, else
  /// std::invalid_argument). Sampling uses this policy's own generator, seeded by `seed`.
  std::vector<float> act(const Observation& observation, bool deterministic);
  void seed(std::uint64_t seed);

  const ObservationSpace& observation_space() const { return observations_; }
  /// The file's metadata; empty for files written before metadata existed (they are
  /// convoy_follow policies on the paper observation).
  const PolicyMetadata& metadata() const { return metadata_; }
  const Box& action_space() const { return actions_; }

 private:
  std::shared_ptr<ppo::ActorCritic> model_;
  ppo::RunningNormalizer normalizer_;
  ObservationSpace observations_;
  Box actions_;
  PolicyMetadata metadata_;
  at::Generator generator_;
};

}  // namespace syndds::learn
