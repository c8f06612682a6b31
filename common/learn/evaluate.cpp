#include "learn/evaluate.hpp"

#include <cmath>
#include <memory>
#include <random>
#include <stdexcept>

namespace syndds::learn {

EvaluationSummary evaluate(Env& env, const PolicyFunction& policy, std::uint64_t first_seed,
                           int episodes, int max_steps, const StepTrace& trace) {
  if (episodes < 1) throw std::invalid_argument("evaluate: episodes must be >= 1");
  EvaluationSummary s;
  std::map<std::string, double> info_sum;
  std::int64_t all_steps = 0;
  const Box actions = env.action_space();
  std::vector<double> sq(actions.size(), 0.0), active_sq(actions.size(), 0.0);
  std::vector<std::int64_t> active(actions.size(), 0);
  std::int64_t taught_steps = 0;
  for (int k = 0; k < episodes; ++k) {
    EpisodeSummary e;
    e.seed = first_seed + static_cast<std::uint64_t>(k);
    Observation o = env.reset(e.seed);
    while (e.steps < max_steps) {
      const std::vector<float> a = policy(o);
      const std::vector<float> teacher = env.expert_action();
      if (teacher.size() == actions.size() && a.size() == actions.size()) {
        ++taught_steps;
        for (std::size_t i = 0; i < a.size(); ++i) {
          const double d = static_cast<double>(a[i]) - static_cast<double>(teacher[i]);
          sq[i] += d * d;
          if (teacher[i] != 0.0f) {
            active_sq[i] += d * d;
            ++active[i];
          }
        }
      }
      const StepResult r = env.step(a);
      if (trace) trace(e.seed, e.steps, o, a, teacher, r);
      ++e.steps;
      e.total_reward += r.reward;
      for (const auto& [key, v] : r.info) info_sum[key] += v;
      e.final_info = r.info;
      o = r.observation;
      if (r.terminated || r.truncated) {
        e.terminated = r.terminated;
        break;
      }
    }
    all_steps += e.steps;
    s.terminated += e.terminated ? 1 : 0;
    s.episodes.push_back(std::move(e));
  }
  const double n = static_cast<double>(episodes);
  for (const auto& e : s.episodes) s.mean_return += e.total_reward / n;
  for (const auto& e : s.episodes) {
    s.std_return += (e.total_reward - s.mean_return) * (e.total_reward - s.mean_return) / n;
  }
  s.std_return = std::sqrt(s.std_return);
  s.mean_steps = static_cast<double>(all_steps) / n;
  for (const auto& [key, sum] : info_sum) {
    s.mean_info[key] = sum / static_cast<double>(std::max<std::int64_t>(1, all_steps));
  }
  if (taught_steps > 0) {
    for (std::size_t i = 0; i < actions.size(); ++i) {
      const std::string name = i < actions.names.size() ? actions.names[i] : "action_" + std::to_string(i);
      EvaluationSummary::TeacherDistance t;
      t.rms = std::sqrt(sq[i] / static_cast<double>(taught_steps));
      t.active_steps = active[i];
      t.active_rms = active[i] > 0 ? std::sqrt(active_sq[i] / static_cast<double>(active[i])) : 0.0;
      s.to_teacher[name] = t;
    }
  }
  return s;
}

PolicyFunction random_policy(const Box& actions, std::uint64_t seed) {
  auto rng = std::make_shared<std::mt19937_64>(seed);
  return [rng, actions](const Observation&) {
    std::vector<float> a(actions.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      const double u = static_cast<double>((*rng)() >> 11) * 0x1.0p-53;  // [0, 1)
      a[i] = static_cast<float>(actions.low[i] + u * (actions.high[i] - actions.low[i]));
    }
    return a;
  };
}

PolicyFunction zero_policy(const Box& actions) {
  return [n = actions.size()](const Observation&) { return std::vector<float>(n, 0.0f); };
}

}  // namespace syndds::learn
