#include "learn/ppo/networks.hpp"

#include <cmath>
#include <cstring>
#include <stdexcept>

namespace syndds::learn::ppo {
namespace {

namespace nn = torch::nn;

nn::Linear linear(int in, int out, double gain) {
  nn::Linear l(in, out);
  torch::NoGradGuard no_grad;
  nn::init::orthogonal_(l->weight, gain);
  nn::init::zeros_(l->bias);
  return l;
}

nn::Conv2d conv(int in, int out, int kernel, int stride) {
  nn::Conv2d c(nn::Conv2dOptions(in, out, kernel).stride(stride));
  torch::NoGradGuard no_grad;
  nn::init::orthogonal_(c->weight, std::sqrt(2.0));
  nn::init::zeros_(c->bias);
  return c;
}

// The camera stack of every network with an image (Nature-DQN), flattened.
nn::Sequential camera_stack(int channels) {
  return nn::Sequential(conv(channels, 32, 8, 4), nn::ReLU(), conv(32, 64, 4, 2), nn::ReLU(),
                        conv(64, 64, 3, 1), nn::ReLU(), nn::Flatten());
}

int stack_features(nn::Sequential& stack, const ImageSpec& image) {
  torch::NoGradGuard no_grad;
  return static_cast<int>(
      stack->forward(torch::zeros({1, image.channels, image.height, image.width})).size(1));
}

}  // namespace

MlpActorCritic::MlpActorCritic(int observation_size, int action_size, int hidden) {
  const double g = std::sqrt(2.0);
  actor_ = register_module("actor", nn::Sequential(linear(observation_size, hidden, g), nn::Tanh(),
                                                   linear(hidden, hidden, g), nn::Tanh(),
                                                   linear(hidden, action_size, 0.01)));
  critic_ = register_module("critic", nn::Sequential(linear(observation_size, hidden, g),
                                                     nn::Tanh(), linear(hidden, hidden, g),
                                                     nn::Tanh(), linear(hidden, 1, 1.0)));
  log_std = register_parameter("log_std", torch::zeros({action_size}));
}

ActorCriticOutput MlpActorCritic::forward(const torch::Tensor& vector, const torch::Tensor&) {
  return {actor_->forward(vector), critic_->forward(vector).squeeze(-1)};
}

FusionActorCritic::FusionActorCritic(int observation_size, const ImageSpec& image,
                                     int action_size) {
  const double g = std::sqrt(2.0);
  cnn_ = register_module("cnn", camera_stack(image.channels));
  cnn_features_ = stack_features(cnn_, image);
  vector_fc_ = register_module("vector_fc",
                               nn::Sequential(linear(observation_size, 64, g), nn::ReLU()));
  trunk_ = register_module("trunk", nn::Sequential(linear(cnn_features_ + 64, 256, g), nn::ReLU(),
                                                   linear(256, 128, g), nn::ReLU(),
                                                   linear(128, 64, g), nn::ReLU()));
  mean_head_ = register_module("mean", linear(64, action_size, 0.01));
  value_head_ = register_module("value", linear(64, 1, 1.0));
  log_std = register_parameter("log_std", torch::zeros({action_size}));
}

ActorCriticOutput FusionActorCritic::forward(const torch::Tensor& vector,
                                             const torch::Tensor& image) {
  const torch::Tensor pixels = image.permute({0, 3, 1, 2}).to(torch::kFloat32) / 255.0;
  const torch::Tensor h =
      trunk_->forward(torch::cat({cnn_->forward(pixels), vector_fc_->forward(vector)}, 1));
  return {mean_head_->forward(h), value_head_->forward(h).squeeze(-1)};
}

ResidualFusionActorCritic::ResidualFusionActorCritic(int observation_size,
                                                     const ImageSpec& image, int action_size) {
  const double g = std::sqrt(2.0);
  base_ = register_module("base", std::make_shared<MlpActorCritic>(observation_size, action_size));
  cnn_ = register_module("cnn", camera_stack(image.channels));
  const int features = stack_features(cnn_, image);
  branch_ = register_module(
      "branch", nn::Sequential(linear(features + observation_size, 64, g), nn::ReLU()));
  mean_head_ = register_module("mean", linear(64, action_size, 0.0));
  value_head_ = register_module("value", linear(64, 1, 0.0));
  log_std = base_->log_std;  // one parameter, registered by the base
}

ActorCriticOutput ResidualFusionActorCritic::forward(const torch::Tensor& vector,
                                                     const torch::Tensor& image) {
  const ActorCriticOutput b = base_->forward(vector, image);
  const torch::Tensor pixels = image.permute({0, 3, 1, 2}).to(torch::kFloat32) / 255.0;
  const torch::Tensor h = branch_->forward(torch::cat({cnn_->forward(pixels), vector}, 1));
  return {b.mean + mean_head_->forward(h), b.value + value_head_->forward(h).squeeze(-1)};
}

PerceptionNet::PerceptionNet(const ImageSpec& image, int outputs) : outputs_(outputs) {
  if (outputs < 1) throw std::invalid_argument("PerceptionNet: needs outputs >= 1");
  cnn_ = register_module("cnn", camera_stack(image.channels));
  const int features = stack_features(cnn_, image);
  head_ = register_module("head", nn::Sequential(linear(features, 256, std::sqrt(2.0)), nn::ReLU(),
                                                 linear(256, outputs, 1.0)));
}

torch::Tensor PerceptionNet::forward(const torch::Tensor& image) {
  const torch::Tensor pixels = image.permute({0, 3, 1, 2}).to(torch::kFloat32) / 255.0;
  return head_->forward(cnn_->forward(pixels));
}

std::shared_ptr<ActorCritic> make_actor_critic(const std::string& kind,
                                               const ObservationSpace& observations,
                                               const Box& actions) {
  const int d = static_cast<int>(observations.vector.size());
  const int a = static_cast<int>(actions.size());
  const bool image = observations.image.has_value();
  if (kind == "mlp" || (kind == "auto" && !image)) {
    return std::make_shared<MlpActorCritic>(d, a);
  }
  if (kind == "residual_fusion") {
    if (!image) throw std::invalid_argument("network residual_fusion needs observations with an image");
    return std::make_shared<ResidualFusionActorCritic>(d, *observations.image, a);
  }
  if (kind == "fusion" || kind == "auto") {
    if (!image) throw std::invalid_argument("network fusion needs observations with an image");
    return std::make_shared<FusionActorCritic>(d, *observations.image, a);
  }
  throw std::invalid_argument("unknown network " + kind +
                              " (mlp, fusion, residual_fusion or auto)");
}

torch::Tensor image_batch(const std::vector<const std::vector<std::uint8_t>*>& images,
                          const ImageSpec& spec) {
  const auto n = static_cast<std::int64_t>(images.size());
  torch::Tensor out = torch::empty({n, spec.height, spec.width, spec.channels}, torch::kUInt8);
  auto* dst = out.data_ptr<std::uint8_t>();
  for (const auto* img : images) {
    if (img->size() != spec.bytes()) {
      throw std::invalid_argument("image of " + std::to_string(img->size()) + " bytes, expected " +
                                  std::to_string(spec.bytes()));
    }
    std::memcpy(dst, img->data(), img->size());
    dst += img->size();
  }
  return out;
}

torch::Tensor jitter_colours(const torch::Tensor& img, double j, at::Generator& generator) {
  if (!img.defined() || j <= 0.0) return img;
  const std::int64_t n = img.size(0), channels = img.size(3);
  const torch::Tensor gain =
      at::empty({n, 1, 1, channels}, torch::kFloat32).uniform_(1.0 - j, 1.0 + j, generator);
  const torch::Tensor offset =
      at::empty({n, 1, 1, 1}, torch::kFloat32).uniform_(-128.0 * j, 128.0 * j, generator);
  return (img.to(torch::kFloat32) * gain + offset).clamp(0.0, 255.0);
}

}  // namespace syndds::learn::ppo
