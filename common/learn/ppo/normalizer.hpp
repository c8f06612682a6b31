#pragma once
// Running normalisation of observation vectors: per dimension mean and variance of every
// observation seen so far, merged batch by batch (Chan et al.'s parallel form of Welford's
// update, in double), and normalise(x) = clamp((x - mean) / sqrt(var + 1e-8), -10, 10). The
// variance is the population one (divided by the count). Images are not normalised. Saved with
// the model: a policy normalises exactly as during training.
#include <torch/torch.h>

#include <cstdint>
#include <span>
#include <vector>

namespace syndds::learn::ppo {

class RunningNormalizer {
 public:
  static constexpr double kClip = 10.0;
  static constexpr double kEpsilon = 1e-8;

  explicit RunningNormalizer(int size = 0);

  int size() const { return static_cast<int>(mean_.size()); }
  double count() const { return count_; }
  const std::vector<double>& mean() const { return mean_; }
  const std::vector<double>& variance() const { return var_; }

  /// Merges a batch of observations (each of size()).
  void update(const std::vector<std::span<const float>>& batch);
  void update(std::span<const float> x) { update(std::vector<std::span<const float>>{x}); }
  /// The normalised observation (floats).
  std::vector<float> normalize(std::span<const float> x) const;

  void save(torch::serialize::OutputArchive& archive) const;
  void load(torch::serialize::InputArchive& archive);

 private:
  std::vector<double> mean_, var_;
  double count_ = 0.0;
};

}  // namespace syndds::learn::ppo
