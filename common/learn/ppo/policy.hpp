#pragma once
// A trained policy for inference (a controller driving with it): the file Trainer::save_policy
// writes (syndds_train's policy.pt) holds the network, the observation normaliser and the
// spaces. act() normalises the observation as in training and returns the Gaussian policy's
// mean (deterministic) or a sample, clamped to the action box either way. The network lives
// behind this interface (policy.cpp), so users of a policy compile without libtorch's headers.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "learn/env.hpp"
#include "learn/policy_metadata.hpp"

namespace syndds::learn {

/// Copies share the network and the sampling generator (as libtorch's handles do); load() and
/// seed() on one copy change that copy only.
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
  struct Net;  // the network, the normaliser and the sampling generator (policy.cpp)
  std::shared_ptr<Net> net_;
  ObservationSpace observations_;
  Box actions_;
  PolicyMetadata metadata_;
};

}  // namespace syndds::learn
