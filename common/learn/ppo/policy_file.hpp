#pragma once
// The policy file (syndds_train's policy.pt, read by learn::Policy) as libtorch archives: the
// writer the trainer uses, and the tensor reader the policy and the trainer's checkpoint share.
#include <torch/torch.h>

#include <string>

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
