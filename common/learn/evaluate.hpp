#pragma once
// Evaluating a policy on an environment: episodes with fixed seeds (not those of training:
// VectorEnv's episode seeds are hashes), the mean return, and the step-mean of every `info`
// number (distance to the leader, collisions, ...). The same seeds give the same numbers.
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "learn/env.hpp"

namespace syndds::learn {

using PolicyFunction = std::function<std::vector<float>(const Observation&)>;

struct EpisodeSummary {
  std::uint64_t seed = 0;
  double total_reward = 0.0;
  int steps = 0;
  bool terminated = false;  // ended by the environment (collision, ...), not cut
  std::map<std::string, double> final_info;  // info of the last step
};

struct EvaluationSummary {
  std::vector<EpisodeSummary> episodes;
  double mean_return = 0.0;
  double std_return = 0.0;  // population standard deviation over the episodes
  double mean_steps = 0.0;
  int terminated = 0;       // episodes the environment ended
  std::map<std::string, double> mean_info;  // mean over every step of every episode
  /// How far the actions were from the environment's expert (Env::expert_action) in the
  /// states the policy visited, per action dimension (by its name in the action space): the
  /// root mean square of the difference over every step ("rms"), and over the steps where
  /// the expert's value was not 0 ("active": e.g. a memory only a few states need). Empty
  /// when the environment has no expert.
  struct TeacherDistance {
    double rms = 0.0;
    double active_rms = 0.0;
    std::int64_t active_steps = 0;
  };
  std::map<std::string, TeacherDistance> to_teacher;
};

/// One step of an evaluation as it happened: the episode's seed, the step's index (from 0), the
/// observation the policy acted on, its action, the expert's action in that state (empty
/// without an expert) and what the step returned.
using StepTrace = std::function<void(std::uint64_t seed, int step, const Observation& seen,
                                     const std::vector<float>& action,
                                     const std::vector<float>& teacher, const StepResult& result)>;

/// Runs `episodes` episodes seeded first_seed, first_seed + 1, ..., each to its end or
/// `max_steps`, with `policy` choosing the actions; `trace`, if given, sees every step.
EvaluationSummary evaluate(Env& env, const PolicyFunction& policy, std::uint64_t first_seed,
                           int episodes, int max_steps = 100000, const StepTrace& trace = {});

/// Uniform random actions in the action box, from a generator seeded with `seed`.
PolicyFunction random_policy(const Box& actions, std::uint64_t seed);
/// Zero actions (for a convoy follower: straight ahead, coasting).
PolicyFunction zero_policy(const Box& actions);

}  // namespace syndds::learn
