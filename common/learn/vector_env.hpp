#pragma once
// K copies of an environment stepped together on a thread pool (OpenAI Baselines' vectorised
// environments, in one process): copy i steps on its own state only, so the results are the
// same whatever K's split over threads. A copy whose episode ends is reset at once with its
// next episode seed (episode_seed(seed, i, n)); the step result then carries the next
// episode's first observation and `final_observation` the last one of the ended episode (what a
// trainer bootstraps a truncated episode's value from).
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "core/thread_pool.hpp"
#include "learn/env.hpp"

namespace syndds::learn {

struct VectorStepResult {
  std::vector<StepResult> results;                       // one per copy
  std::vector<std::optional<Observation>> final_observations;  // set where an episode ended
};

/// Takes one step's results in: each copy's next observation moved into `observations`, and
/// `episodes[i]` counted up where copy i's episode ended in it. Returns how many ended.
std::int64_t take_step(VectorStepResult& step, std::vector<Observation>& observations,
                       std::vector<std::int64_t>& episodes);

class VectorEnv {
 public:
  /// `copies` >= 1 environments from `factory`, stepped by `threads` >= 1 threads.
  VectorEnv(const EnvFactory& factory, int copies, int threads);

  int size() const { return static_cast<int>(envs_.size()); }
  ObservationSpace observation_space() const { return envs_.front()->observation_space(); }
  Box action_space() const { return envs_.front()->action_space(); }
  Env& copy(int i) { return *envs_.at(static_cast<std::size_t>(i)); }

  /// Resets every copy: copy i starts episode 0 with episode_seed(seed, i, 0).
  std::vector<Observation> reset(std::uint64_t seed);
  /// One action per copy (each of the action space's size).
  VectorStepResult step(const std::vector<std::vector<float>>& actions);

  /// The seed of the last reset, and the episodes started per copy since (copy i is in its
  /// episode episodes()[i] - 1): with the actions of the current episodes, what restore needs.
  std::uint64_t seed() const { return seed_; }
  const std::vector<std::uint64_t>& episodes() const { return episodes_; }
  /// Puts every copy back where a run reset with `seed` was (a trainer resuming from a
  /// checkpoint): copy i restarts its episode episodes[i] - 1 and replays `actions[i]`, the
  /// actions step was given since that episode began. Relies on environments being
  /// deterministic for a seed. Returns the current observations. Throws std::invalid_argument
  /// for sizes that do not match the copies, std::runtime_error if a replayed episode ends.
  std::vector<Observation> restore(std::uint64_t seed, const std::vector<std::uint64_t>& episodes,
                                   const std::vector<std::vector<std::vector<float>>>& actions);

 private:
  std::vector<std::unique_ptr<Env>> envs_;
  std::vector<std::uint64_t> episodes_;  // episodes started per copy
  std::uint64_t seed_ = 0;
  bool reset_done_ = false;
  ThreadPool pool_;
};

}  // namespace syndds::learn
