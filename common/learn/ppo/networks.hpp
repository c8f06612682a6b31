#pragma once
// The actor-critic networks of the PPO trainer. Both map a batch of (normalised) observation
// vectors [B, D] and, for the sensor-fusion network, camera images [B, H, W, 3] (uint8, as the
// environments give them) to the Gaussian policy's mean [B, A] and the value [B]; the policy's
// log standard deviation is one learned parameter per action dimension, independent of the
// state.
//  - MlpActorCritic: separate actor and critic trunks, each two hidden layers of 64, tanh.
//  - FusionActorCritic (the JCISE 2022 paper's sensor fusion): a Nature-DQN convolutional stack
//    on the image (8x8 stride 4, 32 filters; 4x4 stride 2, 64; 3x3 stride 1, 64; ReLU; an
//    80 x 45 image gives 64 x 2 x 6 = 768 features), one fully connected layer of 64 on the
//    vector, the two concatenated, then three fully connected layers (256, 128, 64, ReLU) shared
//    by the policy-mean and value heads. Images become float C x H x W in [0, 1].
// Hidden layers are initialised orthogonally with gain sqrt(2), the mean head with 0.01 and the
// value head with 1, biases 0 (what PPO implementations usually do); the log-std starts at 0.
#include <torch/torch.h>

#include <memory>
#include <optional>
#include <string>

#include "learn/env.hpp"

namespace syndds::learn::ppo {

struct ActorCriticOutput {
  torch::Tensor mean;   // [B, A]
  torch::Tensor value;  // [B]
};

class ActorCritic : public torch::nn::Module {
 public:
  /// `image` is undefined for networks without a camera input.
  virtual ActorCriticOutput forward(const torch::Tensor& vector, const torch::Tensor& image) = 0;
  /// "mlp" or "fusion".
  virtual std::string kind() const = 0;
  torch::Tensor log_std;  // [A]
};

class MlpActorCritic final : public ActorCritic {
 public:
  MlpActorCritic(int observation_size, int action_size, int hidden = 64);
  ActorCriticOutput forward(const torch::Tensor& vector, const torch::Tensor& image) override;
  std::string kind() const override { return "mlp"; }

 private:
  torch::nn::Sequential actor_{nullptr}, critic_{nullptr};
};

class FusionActorCritic final : public ActorCritic {
 public:
  FusionActorCritic(int observation_size, const ImageSpec& image, int action_size);
  ActorCriticOutput forward(const torch::Tensor& vector, const torch::Tensor& image) override;
  std::string kind() const override { return "fusion"; }
  /// Features out of the convolutional stack for the image size given.
  int cnn_features() const { return cnn_features_; }

 private:
  torch::nn::Sequential cnn_{nullptr}, vector_fc_{nullptr}, trunk_{nullptr};
  torch::nn::Linear mean_head_{nullptr}, value_head_{nullptr};
  int cnn_features_ = 0;
};

/// Sensor fusion as a residual on a vector policy: the MlpActorCritic on the vector (`base`,
/// which a vector policy of an earlier stage initialises: Trainer::initialize_from_policy), plus
/// a camera branch (the same convolutional stack as FusionActorCritic, its 768 features and the
/// vector through one layer of 64, ReLU) whose mean and value heads start at zero. At
/// initialisation from a vector policy it acts exactly as that policy; training then learns
/// what the image adds. The log standard deviation is the base's.
class ResidualFusionActorCritic final : public ActorCritic {
 public:
  ResidualFusionActorCritic(int observation_size, const ImageSpec& image, int action_size);
  ActorCriticOutput forward(const torch::Tensor& vector, const torch::Tensor& image) override;
  std::string kind() const override { return "residual_fusion"; }
  MlpActorCritic& base() { return *base_; }

 private:
  std::shared_ptr<MlpActorCritic> base_;
  torch::nn::Sequential cnn_{nullptr}, branch_{nullptr};
  torch::nn::Linear mean_head_{nullptr}, value_head_{nullptr};
};

/// The policies' camera stack (Nature-DQN, 8x8/4 32, 4x4/2 64, 3x3/1 64, ReLU),
/// then a fully connected layer of 256 (ReLU) and a linear head of `outputs`. Images
/// [B, H, W, C] of pixel values in [0, 255] (any type) -> [B, outputs].
class PerceptionNet : public torch::nn::Module {
 public:
  PerceptionNet(const ImageSpec& image, int outputs);
  torch::Tensor forward(const torch::Tensor& image);
  int outputs() const { return outputs_; }

 private:
  torch::nn::Sequential cnn_{nullptr}, head_{nullptr};
  int outputs_ = 0;
};

/// The network for an observation space: "mlp" (vector only), "fusion" or "residual_fusion"
/// (need an image) or "auto" (fusion when the observations have an image). Throws
/// std::invalid_argument otherwise.
std::shared_ptr<ActorCritic> make_actor_critic(const std::string& kind,
                                               const ObservationSpace& observations,
                                               const Box& actions);

/// Images as the networks take them: [B, H, W, C] uint8 from B observations' bytes.
torch::Tensor image_batch(const std::vector<const std::vector<std::uint8_t>*>& images,
                          const ImageSpec& spec);

/// Images [B, H, W, C] with their colours changed (data augmentation; `j` in [0, 1)): each
/// image's channels scaled by factors drawn uniformly from [1 - j, 1 + j], then an offset drawn
/// uniformly from [-128 j, 128 j] added to all channels, clamped to [0, 255] (float). The
/// images unchanged when undefined or j <= 0. The networks take pixel values of any type.
torch::Tensor jitter_colours(const torch::Tensor& images, double j, at::Generator& generator);

}  // namespace syndds::learn::ppo
