#include "learn/ppo/trainer.hpp"

#include <ATen/CPUGeneratorImpl.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "learn/ppo/policy.hpp"
#include "learn/ppo/policy_file.hpp"

namespace syndds::learn::ppo {
namespace {

// `explored`: [A] of 1 for the explored dimensions, 0 for the others (Box::explore), which
// count neither in the probability nor in the entropy.
torch::Tensor log_prob(const torch::Tensor& action, const torch::Tensor& mean,
                       const torch::Tensor& log_std, const torch::Tensor& explored) {
  const torch::Tensor z = (action - mean) * torch::exp(-log_std);
  return ((-0.5 * z * z - log_std - 0.5 * std::log(2.0 * std::numbers::pi)) * explored).sum(-1);
}

torch::Tensor doubles(const std::vector<double>& v) {
  return torch::tensor(at::ArrayRef<double>(v), torch::kFloat64);
}

std::vector<double> doubles(const torch::Tensor& t) {
  const torch::Tensor c = t.contiguous().to(torch::kFloat64);
  return {c.data_ptr<double>(), c.data_ptr<double>() + c.numel()};
}

std::int64_t int_of(torch::serialize::InputArchive& archive, const std::string& key) {
  return read_tensor(archive, key).item<std::int64_t>();
}

torch::Tensor int_tensor(std::int64_t v) { return torch::tensor(v, torch::kInt64); }

std::vector<std::span<const float>> spans(const std::vector<Observation>& obs) {
  std::vector<std::span<const float>> out;
  for (const auto& o : obs) out.emplace_back(o.vector);
  return out;
}

std::vector<const Observation*> pointers(const std::vector<Observation>& obs) {
  std::vector<const Observation*> out;
  for (const auto& o : obs) out.push_back(&o);
  return out;
}

}  // namespace

Gae compute_gae(const std::vector<double>& rewards, const std::vector<double>& values,
                const std::vector<double>& next_values, const std::vector<bool>& terminated,
                const std::vector<bool>& truncated, int steps, int copies, double gamma,
                double lambda) {
  const auto n = static_cast<std::size_t>(steps) * static_cast<std::size_t>(copies);
  if (rewards.size() != n || values.size() != n || next_values.size() != n ||
      terminated.size() != n || truncated.size() != n) {
    throw std::invalid_argument("compute_gae: every input needs steps x copies values");
  }
  Gae g;
  g.advantages.assign(n, 0.0);
  g.returns.assign(n, 0.0);
  const auto k_count = static_cast<std::size_t>(copies);
  std::vector<double> next_advantage(k_count, 0.0);
  for (int t = steps - 1; t >= 0; --t) {
    for (std::size_t k = 0; k < k_count; ++k) {
      const std::size_t i = static_cast<std::size_t>(t) * k_count + k;
      const bool ended = terminated[i] || truncated[i];
      const double next_value = terminated[i] ? 0.0 : next_values[i];
      const double delta = rewards[i] + gamma * next_value - values[i];
      const double a = delta + (ended ? 0.0 : gamma * lambda * next_advantage[k]);
      g.advantages[i] = a;
      g.returns[i] = a + values[i];
      next_advantage[k] = a;
    }
  }
  return g;
}

Trainer::Trainer(EnvFactory factory, TrainerOptions options)
    : options_(std::move(options)),
      envs_(factory, options_.copies, options_.threads),
      observation_space_(envs_.observation_space()),
      action_space_(envs_.action_space()),
      generator_(at::make_generator<at::CPUGeneratorImpl>(options_.seed)) {
  const PpoOptions& p = options_.ppo;
  if (p.steps_per_update < 1) throw std::invalid_argument("steps_per_update must be >= 1");
  if (p.epochs < 1) throw std::invalid_argument("epochs must be >= 1");
  if (p.minibatch < 2) throw std::invalid_argument("minibatch must be >= 2");
  if (options_.torch_threads < 1) throw std::invalid_argument("torch_threads must be >= 1");
  if (options_.return_window < 1) throw std::invalid_argument("return_window must be >= 1");
  at::set_num_threads(options_.torch_threads);
  steps_ = (p.steps_per_update + options_.copies - 1) / options_.copies;
  std::vector<float> explored(action_space_.size());
  for (std::size_t i = 0; i < explored.size(); ++i) explored[i] = action_space_.explored(i) ? 1.0f : 0.0f;
  explored_ = torch::tensor(explored);
  torch::manual_seed(options_.seed);  // the networks' initial weights
  model_ = make_actor_critic(options_.network, observation_space_, action_space_);
  optimizer_ = std::make_unique<torch::optim::Adam>(
      model_->parameters(), torch::optim::AdamOptions(p.learning_rate).eps(p.adam_epsilon));
  normalizer_ = RunningNormalizer(static_cast<int>(observation_space_.vector.size()));
  const auto k = static_cast<std::size_t>(options_.copies);
  observations_ = envs_.reset(options_.seed);
  episode_actions_.assign(k, {});
  episode_returns_.assign(k, 0.0);
  discounted_returns_.assign(k, 0.0);
}

torch::Tensor Trainer::vector_tensor(const std::vector<const Observation*>& obs) const {
  const auto d = static_cast<std::int64_t>(normalizer_.size());
  torch::Tensor out = torch::empty({static_cast<std::int64_t>(obs.size()), d}, torch::kFloat32);
  float* dst = out.data_ptr<float>();
  for (const auto* o : obs) {
    const std::vector<float> z = normalizer_.normalize(o->vector);
    dst = std::copy(z.begin(), z.end(), dst);
  }
  return out;
}

torch::Tensor Trainer::image_tensor(const std::vector<const Observation*>& obs) const {
  if (!observation_space_.image) return {};
  std::vector<const std::vector<std::uint8_t>*> images;
  for (const auto* o : obs) images.push_back(&o->image);
  return image_batch(images, *observation_space_.image);
}

double Trainer::scaled_reward(std::size_t copy, double reward, bool ended) {
  if (!options_.ppo.normalize_rewards) return reward;
  discounted_returns_[copy] = discounted_returns_[copy] * options_.ppo.gamma + reward;
  const float r = static_cast<float>(discounted_returns_[copy]);
  return_normalizer_.update(std::span<const float>(&r, 1));
  if (ended) discounted_returns_[copy] = 0.0;
  const double s = reward / std::sqrt(return_normalizer_.variance()[0] + RunningNormalizer::kEpsilon);
  return std::clamp(s, -RunningNormalizer::kClip, RunningNormalizer::kClip);
}

UpdateStats Trainer::update() {
  const PpoOptions& p = options_.ppo;
  const int K = options_.copies;
  const auto k_count = static_cast<std::size_t>(K);
  const int T = steps_;
  const auto n = static_cast<std::size_t>(T) * k_count;
  const auto a_size = static_cast<std::int64_t>(action_space_.size());

  std::vector<torch::Tensor> obs_steps, image_steps, action_steps, logp_steps, expert_steps;
  const double imitation =
      options_.imitation_updates > 0
          ? options_.imitation_weight *
                std::max(0.0, 1.0 - static_cast<double>(updates_) / options_.imitation_updates)
          : options_.imitation_weight;
  std::vector<double> values(n), next_values(n, 0.0), rewards(n);
  std::vector<bool> terminated(n), truncated(n);
  std::vector<double> finished;
  UpdateStats stats;
  const auto t0 = std::chrono::steady_clock::now();

  // Rollout.
  for (int t = 0; t < T; ++t) {
    normalizer_.update(spans(observations_));
    const auto current = pointers(observations_);
    const torch::Tensor vec = vector_tensor(current);
    const torch::Tensor img = image_tensor(current);
    torch::Tensor action, logp, value;
    {
      torch::NoGradGuard no_grad;
      const ActorCriticOutput out = model_->forward(vec, img);
      const torch::Tensor noise =
          at::normal(0.0, 1.0, {K, a_size}, generator_, torch::kFloat32);
      action = out.mean + torch::exp(model_->log_std) * noise * explored_;
      logp = log_prob(action, out.mean, model_->log_std, explored_);
      value = out.value.to(torch::kFloat64).contiguous();
    }
    obs_steps.push_back(vec);
    if (img.defined()) image_steps.push_back(img);
    if (imitation > 0.0) {
      std::vector<float> experts;
      for (int k = 0; k < K; ++k) {
        const std::vector<float> e = envs_.copy(k).expert_action();
        if (e.size() != static_cast<std::size_t>(a_size)) {
          throw std::invalid_argument("Trainer: imitation needs an expert action of " +
                                      std::to_string(a_size) + " values, the environment gave " +
                                      std::to_string(e.size()));
        }
        experts.insert(experts.end(), e.begin(), e.end());
      }
      expert_steps.push_back(torch::tensor(experts).reshape({K, a_size}));
    }
    action_steps.push_back(action);
    logp_steps.push_back(logp);
    std::vector<std::vector<float>> actions(k_count);
    const torch::Tensor ac = action.contiguous();
    for (std::size_t k = 0; k < k_count; ++k) {
      const float* a = ac.data_ptr<float>() + static_cast<std::int64_t>(k) * a_size;
      actions[k].assign(a, a + a_size);
    }
    VectorStepResult res = envs_.step(actions);
    std::vector<std::size_t> bootstrap;
    for (std::size_t k = 0; k < k_count; ++k) {
      const std::size_t i = static_cast<std::size_t>(t) * k_count + k;
      StepResult& r = res.results[k];
      const bool ended = r.terminated || r.truncated;
      values[i] = value.data_ptr<double>()[k];
      rewards[i] = scaled_reward(k, r.reward, ended);
      terminated[i] = r.terminated;
      truncated[i] = r.truncated && !r.terminated;
      episode_returns_[k] += r.reward;
      episode_actions_[k].push_back(std::move(actions[k]));
      if (ended) {
        finished.push_back(episode_returns_[k]);
        episode_returns_[k] = 0.0;
        episode_actions_[k].clear();
      }
      if (truncated[i]) bootstrap.push_back(k);
      observations_[k] = std::move(r.observation);
    }
    if (!bootstrap.empty()) {
      std::vector<const Observation*> finals;
      for (const auto k : bootstrap) finals.push_back(&*res.final_observations[k]);
      torch::NoGradGuard no_grad;
      const torch::Tensor v =
          model_->forward(vector_tensor(finals), image_tensor(finals)).value.to(torch::kFloat64);
      for (std::size_t j = 0; j < bootstrap.size(); ++j) {
        next_values[static_cast<std::size_t>(t) * k_count + bootstrap[j]] =
            v[static_cast<std::int64_t>(j)].item<double>();
      }
    }
  }
  {
    torch::NoGradGuard no_grad;
    const auto current = pointers(observations_);
    const torch::Tensor last =
        model_->forward(vector_tensor(current), image_tensor(current)).value.to(torch::kFloat64);
    for (int t = 0; t < T; ++t) {
      for (std::size_t k = 0; k < k_count; ++k) {
        const std::size_t i = static_cast<std::size_t>(t) * k_count + k;
        if (terminated[i] || truncated[i]) continue;
        next_values[i] = t + 1 < T ? values[i + k_count]
                                   : last[static_cast<std::int64_t>(k)].item<double>();
      }
    }
  }
  const auto t1 = std::chrono::steady_clock::now();
  const Gae gae =
      compute_gae(rewards, values, next_values, terminated, truncated, T, K, p.gamma, p.lambda);

  // Update.
  const torch::Tensor obs = torch::cat(obs_steps);
  const torch::Tensor images = image_steps.empty() ? torch::Tensor() : torch::cat(image_steps);
  const torch::Tensor actions = torch::cat(action_steps);
  const torch::Tensor old_logp = torch::cat(logp_steps);
  const torch::Tensor experts = expert_steps.empty() ? torch::Tensor() : torch::cat(expert_steps);
  const torch::Tensor old_values = doubles(values).to(torch::kFloat32);
  const torch::Tensor advantages = doubles(gae.advantages).to(torch::kFloat32);
  const torch::Tensor returns = doubles(gae.returns).to(torch::kFloat32);
  const auto m = static_cast<std::int64_t>(n);
  double policy_loss = 0.0, value_loss = 0.0, entropy = 0.0, kl = 0.0, clipped = 0.0;
  double imitation_loss = 0.0;
  int batches = 0;
  for (int epoch = 0; epoch < p.epochs; ++epoch) {
    const torch::Tensor perm = torch::randperm(m, generator_, torch::kInt64);
    for (std::int64_t start = 0; start < m; start += p.minibatch) {
      const torch::Tensor idx = perm.slice(0, start, std::min<std::int64_t>(start + p.minibatch, m));
      const ActorCriticOutput out = model_->forward(
          obs.index_select(0, idx), images.defined() ? images.index_select(0, idx) : images);
      const torch::Tensor logp =
          log_prob(actions.index_select(0, idx), out.mean, model_->log_std, explored_);
      const torch::Tensor log_ratio = logp - old_logp.index_select(0, idx);
      const torch::Tensor ratio = torch::exp(log_ratio);
      torch::Tensor adv = advantages.index_select(0, idx);
      if (p.normalize_advantages && adv.size(0) > 1) adv = (adv - adv.mean()) / (adv.std() + 1e-8);
      const torch::Tensor pg =
          torch::max(-adv * ratio, -adv * torch::clamp(ratio, 1.0 - p.clip, 1.0 + p.clip)).mean();
      const torch::Tensor ret = returns.index_select(0, idx);
      torch::Tensor vl = (out.value - ret).pow(2);
      if (p.clip_value) {
        const torch::Tensor old_v = old_values.index_select(0, idx);
        const torch::Tensor v_clipped = old_v + torch::clamp(out.value - old_v, -p.clip, p.clip);
        vl = torch::max(vl, (v_clipped - ret).pow(2));
      }
      vl = 0.5 * vl.mean();
      const torch::Tensor ent =
          ((model_->log_std + 0.5 * (1.0 + std::log(2.0 * std::numbers::pi))) * explored_).sum();
      torch::Tensor loss = pg + p.value_coef * vl - p.entropy_coef * ent;
      torch::Tensor il;
      if (experts.defined()) {
        il = (out.mean - experts.index_select(0, idx)).pow(2).sum(-1).mean();
        loss = loss + imitation * il;
      }
      optimizer_->zero_grad();
      loss.backward();
      torch::nn::utils::clip_grad_norm_(model_->parameters(), p.max_grad_norm);
      optimizer_->step();
      {
        torch::NoGradGuard no_grad;
        policy_loss += pg.item<double>();
        value_loss += vl.item<double>();
        entropy += ent.item<double>();
        kl += ((ratio - 1.0) - log_ratio).mean().item<double>();
        clipped += ((ratio - 1.0).abs() > p.clip).to(torch::kFloat64).mean().item<double>();
        if (il.defined()) imitation_loss += il.item<double>();
      }
      ++batches;
    }
  }

  const auto t2 = std::chrono::steady_clock::now();
  stats.rollout_s = std::chrono::duration<double>(t1 - t0).count();
  stats.learn_s = std::chrono::duration<double>(t2 - t1).count();
  ++updates_;
  interactions_ += static_cast<std::int64_t>(n);
  for (const double r : finished) {
    recent_returns_.push_back(r);
    if (recent_returns_.size() > static_cast<std::size_t>(options_.return_window)) {
      recent_returns_.pop_front();
    }
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  stats.update = updates_;
  stats.interactions = interactions_;
  stats.episodes = static_cast<std::int64_t>(finished.size());
  stats.mean_return = finished.empty()
                          ? nan
                          : std::accumulate(finished.begin(), finished.end(), 0.0) /
                                static_cast<double>(finished.size());
  stats.moving_average_return =
      recent_returns_.empty()
          ? nan
          : std::accumulate(recent_returns_.begin(), recent_returns_.end(), 0.0) /
                static_cast<double>(recent_returns_.size());
  stats.policy_loss = policy_loss / batches;
  stats.value_loss = value_loss / batches;
  stats.entropy = entropy / batches;
  stats.approx_kl = kl / batches;
  stats.clip_fraction = clipped / batches;
  stats.imitation_loss = experts.defined() ? imitation_loss / batches : nan;
  stats.imitation_weight = imitation;
  return stats;
}

std::uint64_t clone_seed(std::uint64_t seed) { return seed ^ 0x9e3779b97f4a7c15ULL; }

CloneStats Trainer::clone(const CloneOptions& c,
                          const std::function<void(const CloneEpoch&)>& progress) {
  if (updates_ > 0) throw std::logic_error("Trainer::clone: only before the first update");
  if (c.steps < 1) throw std::invalid_argument("cloning needs steps >= 1");
  if (c.epochs < 1) throw std::invalid_argument("cloning needs epochs >= 1");
  if (c.minibatch < 2) throw std::invalid_argument("cloning needs a minibatch >= 2");
  if (c.iterations < 1) throw std::invalid_argument("cloning needs iterations >= 1");
  if (!(c.holdout >= 0.0 && c.holdout < 1.0)) {
    throw std::invalid_argument("cloning's held-out share must be in [0, 1)");
  }
  if (!(c.colour_jitter >= 0.0 && c.colour_jitter < 1.0)) {
    throw std::invalid_argument("cloning's colour jitter must be in [0, 1)");
  }
  const int K = options_.copies;
  const auto a_size = static_cast<std::int64_t>(action_space_.size());
  const auto d_size = static_cast<std::size_t>(normalizer_.size());
  CloneStats stats;
  const auto t0 = std::chrono::steady_clock::now();
  double collect_s = 0.0;

  // Every iteration's samples, in the training or the held-out set by the number of their
  // episode within their copy and iteration.
  struct Samples {
    std::vector<float> vectors, experts;  // raw observation vectors
    std::vector<std::uint8_t> images;
    std::int64_t size = 0;
  } train, hold;
  const auto held_out = [&](std::int64_t e) {
    return std::floor(static_cast<double>(e + 1) * c.holdout) >
           std::floor(static_cast<double>(e) * c.holdout);
  };
  const auto rms = [&](const torch::Tensor& sum_squares, std::int64_t n) {
    std::vector<double> out = doubles(sum_squares);
    for (double& v : out) v = std::sqrt(v / static_cast<double>(n));
    return out;
  };
  // A set as tensors, its vectors normalised by the normaliser as it is now (which has seen
  // every sample); the images and expert actions are views of the set's storage.
  const auto tensors = [&](Samples& s) {
    torch::Tensor vec = torch::empty({s.size, static_cast<std::int64_t>(d_size)}, torch::kFloat32);
    float* dst = vec.data_ptr<float>();
    for (std::int64_t i = 0; i < s.size; ++i) {
      const std::vector<float> z = normalizer_.normalize(std::span<const float>(
          s.vectors.data() + static_cast<std::size_t>(i) * d_size, d_size));
      dst = std::copy(z.begin(), z.end(), dst);
    }
    torch::Tensor img;
    if (observation_space_.image) {
      const ImageSpec& spec = *observation_space_.image;
      img = torch::from_blob(s.images.data(), {s.size, spec.height, spec.width, spec.channels},
                             torch::kUInt8);
    }
    torch::Tensor exp = torch::from_blob(s.experts.data(), {s.size, a_size}, torch::kFloat32);
    return std::tuple{vec, img, exp};
  };
  const auto select = [](const torch::Tensor& t, const torch::Tensor& idx) {
    return t.defined() ? t.index_select(0, idx) : t;
  };
  const auto jitter = [&](const torch::Tensor& img) {
    return jitter_colours(img, c.colour_jitter, generator_);
  };
  torch::optim::Adam adam(model_->parameters(), torch::optim::AdamOptions(options_.ppo.learning_rate)
                                                    .eps(options_.ppo.adam_epsilon));

  for (int iteration = 1; iteration <= c.iterations; ++iteration) {
    // Collection: the experts drive the first iteration, the policy's mean action the later
    // ones (DAgger); the expert labels every state.
    const auto tc = std::chrono::steady_clock::now();
    std::vector<Observation> obs =
        envs_.reset(clone_seed(options_.seed) + static_cast<std::uint64_t>(iteration - 1));
    std::vector<std::int64_t> episode(static_cast<std::size_t>(K), 0);
    const std::int64_t steps = (c.steps + K - 1) / K;
    for (std::int64_t t = 0; t < steps; ++t) {
      normalizer_.update(spans(obs));
      std::vector<std::vector<float>> experts(static_cast<std::size_t>(K));
      for (int k = 0; k < K; ++k) {
        const auto ku = static_cast<std::size_t>(k);
        experts[ku] = envs_.copy(k).expert_action();
        if (experts[ku].empty()) {
          throw std::invalid_argument("Trainer: cloning needs an expert, and this environment "
                                      "has none (Env::expert_action)");
        }
        if (experts[ku].size() != static_cast<std::size_t>(a_size)) {
          throw std::invalid_argument("Trainer: cloning needs an expert action of " +
                                      std::to_string(a_size) + " values, the environment gave " +
                                      std::to_string(experts[ku].size()));
        }
        Samples& s = held_out(episode[ku]) ? hold : train;
        s.vectors.insert(s.vectors.end(), obs[ku].vector.begin(), obs[ku].vector.end());
        s.images.insert(s.images.end(), obs[ku].image.begin(), obs[ku].image.end());
        s.experts.insert(s.experts.end(), experts[ku].begin(), experts[ku].end());
        ++s.size;
      }
      std::vector<std::vector<float>> actions;
      if (iteration == 1) {
        actions = std::move(experts);
      } else {
        torch::NoGradGuard no_grad;
        const auto current = pointers(obs);
        const torch::Tensor mean =
            model_->forward(vector_tensor(current), image_tensor(current)).mean.contiguous();
        for (int k = 0; k < K; ++k) {
          const float* m = mean.data_ptr<float>() + static_cast<std::int64_t>(k) * a_size;
          actions.emplace_back(m, m + a_size);
        }
      }
      VectorStepResult res = envs_.step(actions);
      stats.episodes += take_step(res, obs, episode);
    }
    collect_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - tc).count();
    if (train.size < 2) {
      throw std::invalid_argument("cloning collected fewer than 2 training samples");
    }

    // Fitting, on everything collected so far.
    stats.train_samples = train.size;
    stats.holdout_samples = hold.size;
    const auto [train_vec, train_img, train_exp] = tensors(train);
    const auto [hold_vec, hold_img, hold_exp] = tensors(hold);
    const std::vector<double> zero_rms =
        hold.size > 0 ? rms(hold_exp.to(torch::kFloat64).pow(2).sum(0), hold.size)
                      : std::vector<double>{};
    const std::int64_t m = train.size;
    for (int epoch = 1; epoch <= c.epochs; ++epoch) {
      CloneEpoch e;
      e.iteration = iteration;
      e.epoch = epoch;
      e.holdout_zero_rms = zero_rms;
      torch::Tensor squares = torch::zeros({a_size}, torch::kFloat64);
      const torch::Tensor perm = torch::randperm(m, generator_, torch::kInt64);
      for (std::int64_t start = 0; start < m; start += c.minibatch) {
        const torch::Tensor idx =
            perm.slice(0, start, std::min<std::int64_t>(start + c.minibatch, m));
        const torch::Tensor diff =
            model_->forward(train_vec.index_select(0, idx), jitter(select(train_img, idx))).mean -
            train_exp.index_select(0, idx);
        const torch::Tensor loss = diff.pow(2).sum(-1).mean();
        adam.zero_grad();
        loss.backward();
        adam.step();
        squares += diff.detach().to(torch::kFloat64).pow(2).sum(0);
      }
      e.train_rms = rms(squares, m);
      if (hold.size > 0) {
        torch::NoGradGuard no_grad;
        torch::Tensor hs = torch::zeros({a_size}, torch::kFloat64);
        for (std::int64_t start = 0; start < hold.size; start += 1024) {
          const torch::Tensor idx = torch::arange(
              start, std::min<std::int64_t>(start + 1024, hold.size), torch::kInt64);
          hs += (model_->forward(hold_vec.index_select(0, idx), select(hold_img, idx)).mean -
                 hold_exp.index_select(0, idx))
                    .to(torch::kFloat64)
                    .pow(2)
                    .sum(0);
        }
        e.holdout_rms = rms(hs, hold.size);
      }
      if (progress) progress(e);
      stats.epochs.push_back(std::move(e));
    }
  }
  stats.collect_s = collect_s;
  stats.learn_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() - collect_s;

  // PPO starts on the episodes of a run without cloning.
  observations_ = envs_.reset(options_.seed);
  for (auto& a : episode_actions_) a.clear();
  std::fill(episode_returns_.begin(), episode_returns_.end(), 0.0);
  std::fill(discounted_returns_.begin(), discounted_returns_.end(), 0.0);
  return stats;
}

void Trainer::save_checkpoint(const std::string& path) const {
  torch::serialize::OutputArchive archive;
  torch::serialize::OutputArchive model, optimizer, normalizer, return_normalizer;
  model_->save(model);
  optimizer_->save(optimizer);
  normalizer_.save(normalizer);
  return_normalizer_.save(return_normalizer);
  archive.write("model", model);
  archive.write("optimizer", optimizer);
  archive.write("normalizer", normalizer);
  archive.write("return_normalizer", return_normalizer);
  archive.write("network", c10::IValue(model_->kind()));
  archive.write("init_from", c10::IValue(init_from_));
  archive.write("seed", int_tensor(std::bit_cast<std::int64_t>(options_.seed)));
  archive.write("copies", int_tensor(options_.copies));
  archive.write("steps", int_tensor(steps_));
  archive.write("updates", int_tensor(updates_));
  archive.write("interactions", int_tensor(interactions_));
  archive.write("env_seed", int_tensor(std::bit_cast<std::int64_t>(envs_.seed())));
  archive.write("imitation_weight", doubles({options_.imitation_weight}));
  archive.write("imitation_updates", int_tensor(options_.imitation_updates));
  std::vector<std::int64_t> episodes;
  for (const auto e : envs_.episodes()) episodes.push_back(std::bit_cast<std::int64_t>(e));
  archive.write("episodes", torch::tensor(episodes, torch::kInt64));
  const auto a_size = static_cast<std::int64_t>(action_space_.size());
  for (std::size_t k = 0; k < episode_actions_.size(); ++k) {
    std::vector<float> flat;
    for (const auto& a : episode_actions_[k]) flat.insert(flat.end(), a.begin(), a.end());
    archive.write("actions_" + std::to_string(k),
                  torch::tensor(flat, torch::kFloat32).reshape({-1, a_size}));
  }
  archive.write("episode_returns", doubles(episode_returns_));
  archive.write("discounted_returns", doubles(discounted_returns_));
  archive.write("recent_returns",
                doubles(std::vector<double>(recent_returns_.begin(), recent_returns_.end())));
  archive.write("generator", generator_.get_state());
  const std::string tmp = path + ".tmp";
  archive.save_to(tmp);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    throw std::runtime_error("cannot rename " + tmp + " to " + path);
  }
}

void Trainer::initialize_from_policy(const std::string& path) {
  if (updates_ > 0) {
    throw std::logic_error(path + ": a run starts from an earlier policy before its first "
                           "update, not after " + std::to_string(updates_));
  }
  Policy earlier;
  earlier.load(path);
  const ObservationSpace& o = earlier.observation_space();
  if (auto* residual = dynamic_cast<ResidualFusionActorCritic*>(model_.get());
      residual && !o.image) {
    // A vector policy of an earlier stage becomes the residual network's base: the new run
    // starts acting exactly as it did.
    if (o.vector.size() != observation_space_.vector.size() ||
        earlier.action_space().size() != action_space_.size()) {
      throw std::invalid_argument(path + ": its vector observation or action space is not this "
                                  "environment's");
    }
    torch::serialize::InputArchive archive, model, normalizer;
    archive.load_from(path);
    c10::IValue network;
    archive.read("network", network);
    if (network.toStringRef() != "mlp") {
      throw std::invalid_argument(path + " holds a " + network.toStringRef() +
                                  " network; a residual_fusion run starts from an mlp policy");
    }
    archive.read("model", model);
    archive.read("normalizer", normalizer);
    residual->base().load(model);
    normalizer_.load(normalizer);
    init_from_ = std::filesystem::path(path).filename().string();
    return;
  }
  const bool same_image = o.image.has_value() == observation_space_.image.has_value() &&
                          (!o.image || (o.image->width == observation_space_.image->width &&
                                        o.image->height == observation_space_.image->height));
  if (o.vector.size() != observation_space_.vector.size() || !same_image ||
      earlier.action_space().size() != action_space_.size()) {
    throw std::invalid_argument(path + ": its observation or action space is not this "
                                "environment's");
  }
  torch::serialize::InputArchive archive;
  archive.load_from(path);
  c10::IValue network;
  archive.read("network", network);
  if (network.toStringRef() != model_->kind()) {
    throw std::invalid_argument(path + " holds a " + network.toStringRef() +
                                " network, this run has " + model_->kind());
  }
  torch::serialize::InputArchive model, normalizer;
  archive.read("model", model);
  archive.read("normalizer", normalizer);
  model_->load(model);
  normalizer_.load(normalizer);
  init_from_ = std::filesystem::path(path).filename().string();
}

void Trainer::load_checkpoint(const std::string& path) {
  torch::serialize::InputArchive archive;
  archive.load_from(path);
  c10::IValue network;
  archive.read("network", network);
  const auto check = [&](const char* what, std::int64_t saved, std::int64_t mine) {
    if (saved != mine) {
      throw std::invalid_argument(path + " was written with " + what + " " +
                                  std::to_string(saved) + ", this run has " +
                                  std::to_string(mine));
    }
  };
  if (network.toStringRef() != model_->kind()) {
    throw std::invalid_argument(path + " holds a " + network.toStringRef() +
                                " network, this run has " + model_->kind());
  }
  check("seed", int_of(archive, "seed"), std::bit_cast<std::int64_t>(options_.seed));
  check("copies", int_of(archive, "copies"), options_.copies);
  check("steps per copy", int_of(archive, "steps"), steps_);
  // The imitation schedule shapes every later update: a resumed run must have the same one.
  // (A checkpoint written before imitation existed has none: PPO alone.)
  torch::Tensor saved_weight;
  const double weight =
      archive.try_read("imitation_weight", saved_weight) ? doubles(saved_weight).at(0) : 0.0;
  torch::Tensor saved_updates;
  const std::int64_t over = archive.try_read("imitation_updates", saved_updates)
                                ? saved_updates.item<std::int64_t>()
                                : 0;
  if (weight != options_.imitation_weight || over != options_.imitation_updates) {
    const auto schedule = [](double w, std::int64_t n) {
      std::ostringstream out;
      out << "imitation weight " << w << " over " << n << " updates";
      return out.str();
    };
    throw std::invalid_argument(path + " was written with " + schedule(weight, over) +
                                ", this run has " +
                                schedule(options_.imitation_weight, options_.imitation_updates));
  }
  torch::serialize::InputArchive model, optimizer, normalizer, return_normalizer;
  archive.read("model", model);
  archive.read("optimizer", optimizer);
  archive.read("normalizer", normalizer);
  archive.read("return_normalizer", return_normalizer);
  model_->load(model);
  optimizer_->load(optimizer);
  normalizer_.load(normalizer);
  return_normalizer_.load(return_normalizer);
  updates_ = static_cast<int>(int_of(archive, "updates"));
  interactions_ = int_of(archive, "interactions");
  c10::IValue init_from;
  init_from_ = archive.try_read("init_from", init_from) ? init_from.toStringRef() : "";
  const auto env_seed = std::bit_cast<std::uint64_t>(int_of(archive, "env_seed"));
  torch::Tensor t = read_tensor(archive, "episodes");
  std::vector<std::uint64_t> episodes;
  for (std::int64_t k = 0; k < t.numel(); ++k) {
    episodes.push_back(std::bit_cast<std::uint64_t>(t[k].item<std::int64_t>()));
  }
  const auto a_size = static_cast<std::size_t>(action_space_.size());
  for (std::size_t k = 0; k < episode_actions_.size(); ++k) {
    const torch::Tensor c = read_tensor(archive, "actions_" + std::to_string(k)).contiguous();
    const float* a = c.data_ptr<float>();
    episode_actions_[k].clear();
    for (std::int64_t j = 0; j < c.size(0); ++j, a += a_size) {
      episode_actions_[k].emplace_back(a, a + a_size);
    }
  }
  episode_returns_ = doubles(read_tensor(archive, "episode_returns"));
  discounted_returns_ = doubles(read_tensor(archive, "discounted_returns"));
  const std::vector<double> recent = doubles(read_tensor(archive, "recent_returns"));
  recent_returns_.assign(recent.begin(), recent.end());
  generator_.set_state(read_tensor(archive, "generator"));
  observations_ = envs_.restore(env_seed, episodes, episode_actions_);
}

}  // namespace syndds::learn::ppo
