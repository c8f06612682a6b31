#include "learn/vector_env.hpp"

#include <exception>
#include <stdexcept>
#include <string>

#include "core/hash.hpp"

namespace syndds::learn {
std::uint64_t episode_seed(std::uint64_t seed, std::uint64_t copy, std::uint64_t episode) {
  return splitmix64(splitmix64(splitmix64(seed) ^ copy) ^ episode);
}

VectorEnv::VectorEnv(const EnvFactory& factory, int copies, int threads) : pool_(threads) {
  if (copies < 1) throw std::invalid_argument("VectorEnv: copies must be >= 1");
  for (int i = 0; i < copies; ++i) envs_.push_back(factory());
  episodes_.assign(envs_.size(), 0);
}

std::vector<Observation> VectorEnv::reset(std::uint64_t seed) {
  seed_ = seed;
  reset_done_ = true;
  std::vector<Observation> out(envs_.size());
  std::vector<std::exception_ptr> errors(envs_.size());
  pool_.run(size(), [&](int i) {
    const auto k = static_cast<std::size_t>(i);
    try {
      episodes_[k] = 1;
      out[k] = envs_[k]->reset(episode_seed(seed_, k, 0));
    } catch (...) {
      errors[k] = std::current_exception();
    }
  });
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  return out;
}

std::vector<Observation> VectorEnv::restore(
    std::uint64_t seed, const std::vector<std::uint64_t>& episodes,
    const std::vector<std::vector<std::vector<float>>>& actions) {
  if (episodes.size() != envs_.size() || actions.size() != envs_.size()) {
    throw std::invalid_argument("VectorEnv::restore: state of " +
                                std::to_string(episodes.size()) + " copies for " +
                                std::to_string(envs_.size()));
  }
  for (const auto e : episodes) {
    if (e < 1) throw std::invalid_argument("VectorEnv::restore: a copy with no episode started");
  }
  seed_ = seed;
  reset_done_ = true;
  episodes_ = episodes;
  std::vector<Observation> out(envs_.size());
  std::vector<std::exception_ptr> errors(envs_.size());
  pool_.run(size(), [&](int i) {
    const auto k = static_cast<std::size_t>(i);
    try {
      out[k] = envs_[k]->reset(episode_seed(seed_, k, episodes_[k] - 1));
      for (const auto& a : actions[k]) {
        StepResult r = envs_[k]->step(a);
        if (r.terminated || r.truncated) {
          throw std::runtime_error("VectorEnv::restore: copy " + std::to_string(k) +
                                   "'s episode ended during the replay (not deterministic?)");
        }
        out[k] = std::move(r.observation);
      }
    } catch (...) {
      errors[k] = std::current_exception();
    }
  });
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  return out;
}

VectorStepResult VectorEnv::step(const std::vector<std::vector<float>>& actions) {
  if (!reset_done_) throw std::logic_error("VectorEnv::step before reset");
  if (actions.size() != envs_.size()) {
    throw std::invalid_argument("VectorEnv::step: " + std::to_string(actions.size()) +
                                " actions for " + std::to_string(envs_.size()) + " copies");
  }
  VectorStepResult out;
  out.results.resize(envs_.size());
  out.final_observations.resize(envs_.size());
  std::vector<std::exception_ptr> errors(envs_.size());
  pool_.run(size(), [&](int i) {
    const auto k = static_cast<std::size_t>(i);
    try {
      StepResult r = envs_[k]->step(actions[k]);
      if (r.terminated || r.truncated) {
        out.final_observations[k] = std::move(r.observation);
        r.observation = envs_[k]->reset(episode_seed(seed_, k, episodes_[k]++));
      }
      out.results[k] = std::move(r);
    } catch (...) {
      errors[k] = std::current_exception();
    }
  });
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  return out;
}

std::int64_t take_step(VectorStepResult& step, std::vector<Observation>& observations,
                       std::vector<std::int64_t>& episodes) {
  std::int64_t ended = 0;
  for (std::size_t k = 0; k < step.results.size(); ++k) {
    if (step.results[k].terminated || step.results[k].truncated) {
      ++episodes[k];
      ++ended;
    }
    observations[k] = std::move(step.results[k].observation);
  }
  return ended;
}

}  // namespace syndds::learn
