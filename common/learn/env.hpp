#pragma once
// The learning environment API (Gymnasium's, in C++): reset(seed) -> observation,
// step(action) -> {observation, reward, terminated, truncated, info}, and descriptions of the
// observation and action spaces. No DDS, no learning library: environments are plain
// simulations that a trainer (syndds_train, libtorch), the Python binding or a test drives.
//
// Conventions:
//  - An observation is a vector of floats and, for environments with a camera, one RGB image
//    (row-major height x width x 3, bytes 0..255).
//  - Actions are vectors of floats within the action space's box; an environment clamps what
//    is outside (a trainer's Gaussian policy samples beyond the box).
//  - terminated: the episode reached an end state (collision, goal, leader lost), no value
//    beyond it; truncated: it was cut (time limit), its value goes on. After either, reset.
//  - The same seed gives the same episode, bit for bit.
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace syndds::learn {

/// A box of floats, one bound pair per dimension.
struct Box {
  std::vector<float> low;
  std::vector<float> high;
  std::vector<std::string> names;  // one per dimension (documentation, CSV headers)
  /// Actions only: the dimensions a trainer explores in (samples around its mean). Empty:
  /// every one. A dimension that is not explored is acted on as the policy's mean: e.g. a
  /// memory the environment only hands back in the next observation, whose noise would be
  /// noise in the policy's own inputs, not exploration of the world.
  std::vector<bool> explore = {};
  std::size_t size() const { return low.size(); }
  bool explored(std::size_t i) const { return explore.empty() || explore.at(i); }
};

struct ImageSpec {
  int width = 0;
  int height = 0;
  int channels = 3;
  std::size_t bytes() const {
    return static_cast<std::size_t>(width) * static_cast<std::size_t>(height) *
           static_cast<std::size_t>(channels);
  }
};

struct ObservationSpace {
  Box vector;
  std::optional<ImageSpec> image;  // absent: no image in the observations
};

struct Observation {
  std::vector<float> vector;
  std::vector<std::uint8_t> image;  // empty without a camera
};

struct StepResult {
  Observation observation;
  double reward = 0.0;
  bool terminated = false;
  bool truncated = false;
  std::map<std::string, double> info;  // diagnostics (distance to the leader, ...)
};

class Env {
 public:
  virtual ~Env() = default;
  virtual ObservationSpace observation_space() const = 0;
  virtual Box action_space() const = 0;
  /// Starts an episode; the same seed gives the same episode.
  virtual Observation reset(std::uint64_t seed) = 0;
  /// Applies the action for one control period. Calling it before reset, or after an episode
  /// ended, throws std::logic_error.
  virtual StepResult step(std::span<const float> action) = 0;
  /// An expert's action for the current state (after reset or step), within the action
  /// space, for a trainer to imitate; never part of the observation. Empty: this environment
  /// has no expert.
  virtual std::vector<float> expert_action() const { return {}; }
  /// What a perception network is fitted to read from the current observation's image alone
  /// (ppo::fit_perception), from ground truth; never part of the observation. Empty: this
  /// environment has none (or no image).
  virtual std::vector<float> perception_target() const { return {}; }
};

using EnvFactory = std::function<std::unique_ptr<Env>()>;

/// The seed of episode `episode` of copy `copy` in a vector environment reset with `seed`:
/// a fixed hash, so that copy i's episodes do not depend on how many copies there are.
std::uint64_t episode_seed(std::uint64_t seed, std::uint64_t copy, std::uint64_t episode);

}  // namespace syndds::learn
