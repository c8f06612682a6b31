#include "learn/ppo/perception.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "learn/ppo/networks.hpp"

namespace syndds::learn::ppo {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

void PerceptionModel::save(const std::string& path, PerceptionNet& net, const ImageSpec& image) {
  torch::serialize::OutputArchive archive;
  net.save(archive);
  archive.write("perception_outputs", torch::tensor(static_cast<std::int64_t>(net.outputs())));
  archive.write("perception_image",
                torch::tensor({static_cast<std::int64_t>(image.width),
                               static_cast<std::int64_t>(image.height),
                               static_cast<std::int64_t>(image.channels)}));
  archive.save_to(path);
}

PerceptionModel PerceptionModel::load(const std::string& path) {
  try {
    torch::serialize::InputArchive archive;
    archive.load_from(path);
    torch::Tensor outputs, image;
    archive.read("perception_outputs", outputs);
    archive.read("perception_image", image);
    PerceptionModel m;
    m.image_ = ImageSpec{static_cast<int>(image[0].item<std::int64_t>()),
                         static_cast<int>(image[1].item<std::int64_t>()),
                         static_cast<int>(image[2].item<std::int64_t>())};
    m.outputs_ = static_cast<int>(outputs.item<std::int64_t>());
    m.net_ = std::make_shared<PerceptionNet>(m.image_, m.outputs_);
    m.net_->load(archive);
    m.net_->eval();
    return m;
  } catch (const c10::Error& e) {
    throw std::runtime_error(path + ": not a perception file of syndds_train --perceive-steps (" +
                             e.what_without_backtrace() + ")");
  }
}

std::vector<float> PerceptionModel::read(const std::vector<std::uint8_t>& image) const {
  if (image.size() != image_.bytes()) {
    throw std::invalid_argument("PerceptionModel: an image of " + std::to_string(image.size()) +
                                " bytes, the model reads " + std::to_string(image_.bytes()));
  }
  torch::NoGradGuard no_grad;
  const torch::Tensor in = torch::from_blob(const_cast<std::uint8_t*>(image.data()),
                                            {1, image_.height, image_.width, image_.channels},
                                            torch::kUInt8);
  const torch::Tensor out = net_->forward(in).contiguous();
  return std::vector<float>(out.data_ptr<float>(), out.data_ptr<float>() + out.numel());
}

PerceptionStats fit_perception(VectorEnv& envs, std::uint64_t seed, const PerceptionOptions& o,
                               PerceptionNet& net, at::Generator& generator,
                               const std::function<void(const PerceptionEpoch&)>& progress) {
  if (o.steps < 1 || o.epochs < 1 || o.minibatch < 2) {
    throw std::invalid_argument("perception fit: needs steps >= 1, epochs >= 1, minibatch >= 2");
  }
  if (!(o.holdout >= 0.0 && o.holdout < 1.0)) {
    throw std::invalid_argument("perception fit: the held-out share must be in [0, 1)");
  }
  if (!(o.colour_jitter >= 0.0 && o.colour_jitter < 1.0)) {
    throw std::invalid_argument("perception fit: the colour jitter must be in [0, 1)");
  }
  if (!(o.learning_rate > 0.0)) throw std::invalid_argument("perception fit: learning rate <= 0");
  const std::optional<ImageSpec> spec = envs.observation_space().image;
  if (!spec) throw std::invalid_argument("perception fit: the environment's observations have no image");
  const int K = envs.size();
  const std::int64_t outputs = net.outputs();
  PerceptionStats stats;
  const auto t0 = std::chrono::steady_clock::now();

  struct Samples {
    std::vector<std::uint8_t> images;
    std::vector<float> targets;
    std::int64_t size = 0;
  } train, hold;
  const auto held_out = [&](std::int64_t e) {
    return std::floor(static_cast<double>(e + 1) * o.holdout) >
           std::floor(static_cast<double>(e) * o.holdout);
  };
  std::vector<Observation> obs = envs.reset(seed);
  std::vector<std::int64_t> episode(static_cast<std::size_t>(K), 0);
  const std::int64_t steps = (o.steps + K - 1) / K;
  for (std::int64_t t = 0; t < steps; ++t) {
    std::vector<std::vector<float>> actions(static_cast<std::size_t>(K));
    for (int k = 0; k < K; ++k) {
      const auto ku = static_cast<std::size_t>(k);
      actions[ku] = envs.copy(k).expert_action();
      if (actions[ku].empty()) {
        throw std::invalid_argument("perception fit: the environment has no expert to drive it");
      }
      const std::vector<float> target = envs.copy(k).perception_target();
      if (target.empty()) {
        throw std::invalid_argument("perception fit: the environment has no perception target");
      }
      if (static_cast<std::int64_t>(target.size()) != outputs) {
        throw std::invalid_argument("perception fit: a target of " + std::to_string(target.size()) +
                                    " values for a network of " + std::to_string(outputs));
      }
      if (obs[ku].image.size() != spec->bytes()) {
        throw std::invalid_argument("perception fit: an image of " +
                                    std::to_string(obs[ku].image.size()) + " bytes, expected " +
                                    std::to_string(spec->bytes()));
      }
      Samples& s = held_out(episode[ku]) ? hold : train;
      s.images.insert(s.images.end(), obs[ku].image.begin(), obs[ku].image.end());
      s.targets.insert(s.targets.end(), target.begin(), target.end());
      ++s.size;
    }
    VectorStepResult res = envs.step(actions);
    stats.episodes += take_step(res, obs, episode);
  }
  stats.collect_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (train.size < 2) throw std::invalid_argument("perception fit: fewer than 2 training samples");
  stats.train_samples = train.size;
  stats.holdout_samples = hold.size;

  const auto images = [&](Samples& s) {
    return torch::from_blob(s.images.data(), {s.size, spec->height, spec->width, spec->channels},
                            torch::kUInt8);
  };
  const auto targets = [&](Samples& s) {
    return torch::from_blob(s.targets.data(), {s.size, outputs}, torch::kFloat32);
  };
  const torch::Tensor train_img = images(train), train_y = targets(train);
  const torch::Tensor hold_img = hold.size > 0 ? images(hold) : torch::Tensor();
  const torch::Tensor hold_y = hold.size > 0 ? targets(hold) : torch::Tensor();
  const torch::Tensor seen = hold.size > 0 ? hold_y.lt(o.seen_below) : torch::Tensor();
  const std::int64_t n_seen = hold.size > 0 ? seen.sum().item<std::int64_t>() : 0;
  // RMS over all held-out values and over the seen ones, of predictions `p`.
  const auto held_rms = [&](const torch::Tensor& p) {
    const torch::Tensor sq = (p - hold_y).to(torch::kFloat64).pow(2);
    const double all = std::sqrt(sq.mean().item<double>());
    const double on_seen =
        n_seen > 0 ? std::sqrt(sq.masked_select(seen).mean().item<double>()) : kNaN;
    return std::pair{all, on_seen};
  };
  if (hold.size > 0) {
    const auto [all, on_seen] = held_rms(train_y.mean(0, true).expand({hold.size, outputs}));
    stats.holdout_mean_rms = all;
    stats.holdout_mean_seen_rms = on_seen;
    stats.seen_share = static_cast<double>(n_seen) / static_cast<double>(hold.size * outputs);
  } else {
    stats.holdout_mean_rms = stats.holdout_mean_seen_rms = kNaN;
  }

  torch::optim::Adam adam(net.parameters(), torch::optim::AdamOptions(o.learning_rate));
  const std::int64_t m = train.size;
  for (int epoch = 1; epoch <= o.epochs; ++epoch) {
    PerceptionEpoch e;
    e.epoch = epoch;
    double squares = 0.0;
    const torch::Tensor perm = torch::randperm(m, generator, torch::kInt64);
    for (std::int64_t start = 0; start < m; start += o.minibatch) {
      const torch::Tensor idx = perm.slice(0, start, std::min<std::int64_t>(start + o.minibatch, m));
      const torch::Tensor diff =
          net.forward(jitter_colours(train_img.index_select(0, idx), o.colour_jitter, generator)) -
          train_y.index_select(0, idx);
      const torch::Tensor loss = diff.pow(2).mean();
      adam.zero_grad();
      loss.backward();
      adam.step();
      squares += diff.detach().to(torch::kFloat64).pow(2).sum().item<double>();
    }
    e.train_rms = std::sqrt(squares / static_cast<double>(m * outputs));
    e.holdout_rms = e.holdout_seen_rms = kNaN;
    if (hold.size > 0) {
      torch::NoGradGuard no_grad;
      std::vector<torch::Tensor> parts;
      for (std::int64_t start = 0; start < hold.size; start += 1024) {
        parts.push_back(net.forward(hold_img.slice(0, start, std::min<std::int64_t>(start + 1024, hold.size))));
      }
      const auto [all, on_seen] = held_rms(torch::cat(parts, 0));
      e.holdout_rms = all;
      e.holdout_seen_rms = on_seen;
    }
    if (progress) progress(e);
    stats.epochs.push_back(e);
  }
  stats.learn_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() - stats.collect_s;
  return stats;
}

}  // namespace syndds::learn::ppo
