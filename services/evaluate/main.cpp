// syndds_evaluate: policies side by side on a learning environment (docs/learning.md): learned
// ones (syndds_train's policy.pt, deterministic actions) and baselines (zero, random, the
// environment's expert, and for convoy_follow the hand-written follower), each over the same
// episode seeds. Prints one row per policy (mean and spread of the return, episode length,
// episodes ended by the environment, the step-mean of the environment's info numbers) and
// optionally writes a CSV, and with --trace every step of every episode.
#include <ATen/Parallel.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>
#include <iostream>

#include "learn/convoy_env.hpp"
#include "learn/evaluate.hpp"
#include "learn/ppo/perception_model.hpp"
#include "learn/ppo/policy.hpp"
#include "learn/registry.hpp"

using namespace syndds;

int main(int argc, char** argv) {
  CLI::App app{"syndds evaluate: learned policies and baselines on a learning environment"};
  std::string env_name;
  std::vector<std::string> env_option_args, policies, baselines;
  int episodes = 20;
  std::uint64_t first_seed = 1000000;
  std::string csv;
  app.add_option("--env", env_name, "Environment")->required();
  app.add_option("--env-option", env_option_args, "Environment option KEY=VALUE (repeatable)");
  app.add_option("--policy", policies, "A policy file of syndds_train (repeatable)");
  app.add_option("--baseline", baselines,
                 "zero, random, heuristic (convoy_follow) or expert (the teacher a trainer "
                 "imitates: convoy_follow with a trail observation); repeatable")
      ->check(CLI::IsMember({"zero", "random", "heuristic", "expert"}));
  app.add_option("--episodes", episodes, "Episodes per policy")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--first-seed", first_seed, "Seed of the first episode (then +1, +2, ...)")
      ->capture_default_str();
  app.add_option("--csv", csv, "Also write the rows to this CSV file");
  std::string trace_file;
  app.add_option("--trace", trace_file,
                 "Also write every step to this CSV file: policy, seed, step, the observation "
                 "vector, the action, the expert's action (teacher_*), the reward and the info "
                 "numbers (info_*)");
  std::string perception_file;
  app.add_option("--perception", perception_file,
                 "convoy_follow with teacher_view=ranges: the teacher's obstacle readings come "
                 "from this perception network (syndds_train --perceive-steps) reading the "
                 "camera's image, not from the ground truth");
  CLI11_PARSE(app, argc, argv);
  if (policies.empty() && baselines.empty()) {
    std::cerr << "syndds_evaluate: give at least one --policy or --baseline\n";
    return 1;
  }
  at::set_num_threads(1);
  try {
    learn::EnvFactory factory;
    try {
      const learn::EnvOptions options = learn::parse_env_options(env_option_args);
      if (perception_file.empty()) {
        factory = learn::env_factory(env_name, options);
      } else {
        learn::ConvoyEnvOptions o = learn::convoy_env_options(options);
        if (env_name != "convoy_follow" || !o.teacher_view_ranges) {
          std::cerr << "syndds_evaluate: --perception: for convoy_follow with "
                       "teacher_view=ranges\n";
          return 1;
        }
        auto model = std::make_shared<learn::ppo::PerceptionModel>(
            learn::ppo::PerceptionModel::load(perception_file));
        o.perceive_ranges = [model](const learn::Observation& seen) {
          return model->read(seen.image);
        };
        factory = [o] { return learn::make_convoy_env(o); };
      }
    } catch (const std::runtime_error& e) {
      std::cerr << "syndds_evaluate: --perception " << e.what() << "\n";
      return 1;
    } catch (const std::invalid_argument& e) {
      std::cerr << "syndds_evaluate: --env / --env-option: " << e.what() << "\n";
      return 1;
    }
    auto env = factory();
    struct Entry {
      std::string name;
      learn::PolicyFunction act;
    };
    std::vector<Entry> entries;
    std::vector<std::shared_ptr<learn::Policy>> loaded;
    for (const auto& file : policies) {
      auto p = std::make_shared<learn::Policy>();
      try {
        p->load(file);
      } catch (const std::exception& e) {
        std::cerr << "syndds_evaluate: --policy " << file << ": not a policy file (" << e.what()
                  << ")\n";
        return 1;
      }
      if (p->observation_space().vector.size() != env->observation_space().vector.size() ||
          p->observation_space().image.has_value() != env->observation_space().image.has_value() ||
          p->action_space().size() != env->action_space().size()) {
        std::cerr << "syndds_evaluate: --policy " << file << ": its observation or action space "
                  << "is not " << env_name << "'s with these options\n";
        return 1;
      }
      loaded.push_back(p);
      entries.push_back({file, [p](const learn::Observation& o) { return p->act(o, true); }});
    }
    for (const auto& b : baselines) {
      if (b == "zero") entries.push_back({"zero", learn::zero_policy(env->action_space())});
      if (b == "random") entries.push_back({"random", learn::random_policy(env->action_space(), 7)});
      if (b == "heuristic") {
        if (env_name != "convoy_follow") {
          std::cerr << "syndds_evaluate: --baseline heuristic: only for convoy_follow\n";
          return 1;
        }
        const auto options = learn::parse_env_options(env_option_args);
        if (const auto it = options.find("steering");
            it != options.end() && it->second == "residual") {
          std::cerr << "syndds_evaluate: --baseline heuristic: its steering is a command, not a "
                       "correction to the feed-forward (steering=residual)\n";
          return 1;
        }
        entries.push_back({"heuristic", learn::convoy_heuristic_action});
      }
      if (b == "expert") {
        env->reset(first_seed);
        if (env->expert_action().empty()) {
          std::cerr << "syndds_evaluate: --baseline expert: " << env_name
                    << " has no expert with these options\n";
          return 1;
        }
        learn::Env* e = env.get();
        entries.push_back({"expert", [e](const learn::Observation&) { return e->expert_action(); }});
      }
    }
    std::ofstream out;
    if (!csv.empty()) {
      out.open(csv);
      if (!out) {
        std::cerr << "syndds_evaluate: --csv " << csv << ": cannot write\n";
        return 1;
      }
      out << "policy,episodes,first_seed,mean_return,std_return,mean_steps,terminated";
    }
    std::ofstream trace_out;
    bool trace_header = false;
    if (!trace_file.empty()) {
      trace_out.open(trace_file);
      if (!trace_out) {
        std::cerr << "syndds_evaluate: --trace " << trace_file << ": cannot write\n";
        return 1;
      }
      trace_out.precision(9);  // a float's every digit
    }
    const learn::Box action_space = env->action_space();
    const learn::Box observation_vector = env->observation_space().vector;
    const auto name_of = [](const learn::Box& box, std::size_t i, const char* fallback) {
      return i < box.names.size() ? box.names[i] : fallback + std::to_string(i);
    };
    bool header = false;
    for (const auto& e : entries) {
      learn::StepTrace trace;
      if (trace_out.is_open()) {
        trace = [&](std::uint64_t seed, int step, const learn::Observation& seen,
                    const std::vector<float>& action, const std::vector<float>& teacher,
                    const learn::StepResult& r) {
          if (!trace_header) {
            trace_out << "policy,seed,step";
            for (std::size_t i = 0; i < seen.vector.size(); ++i) {
              trace_out << "," << name_of(observation_vector, i, "observation_");
            }
            for (std::size_t i = 0; i < action.size(); ++i) {
              trace_out << "," << name_of(action_space, i, "action_");
            }
            for (std::size_t i = 0; i < action.size(); ++i) {
              trace_out << ",teacher_" << name_of(action_space, i, "action_");
            }
            trace_out << ",reward";
            for (const auto& [k, v] : r.info) trace_out << ",info_" << k;
            trace_out << "\n";
            trace_header = true;
          }
          trace_out << e.name << "," << seed << "," << step;
          for (float v : seen.vector) trace_out << "," << v;
          for (float v : action) trace_out << "," << v;
          for (std::size_t i = 0; i < action.size(); ++i) {
            trace_out << ",";
            if (i < teacher.size()) trace_out << teacher[i];
          }
          trace_out << "," << r.reward;
          for (const auto& [k, v] : r.info) trace_out << "," << v;
          trace_out << "\n";
        };
      }
      const auto s = learn::evaluate(*env, e.act, first_seed, episodes, 100000, trace);
      if (!header) {
        std::printf("%-40s %10s %8s %8s %10s", "policy", "return", "std", "steps", "terminated");
        for (const auto& [k, v] : s.mean_info) std::printf(" %16s", k.c_str());
        for (const auto& [k, t] : s.to_teacher) {
          std::printf(" %24s %24s", ("teacher_rms_" + k).c_str(), ("teacher_active_rms_" + k).c_str());
        }
        std::printf("\n");
        if (out.is_open()) {
          for (const auto& [k, v] : s.mean_info) out << ",mean_" << k;
          for (const auto& [k, t] : s.to_teacher) {
            out << ",teacher_rms_" << k << ",teacher_active_rms_" << k << ",teacher_active_steps_" << k;
          }
          out << "\n";
        }
        header = true;
      }
      std::printf("%-40s %10.1f %8.1f %8.1f %10d", e.name.c_str(), s.mean_return, s.std_return,
                  s.mean_steps, s.terminated);
      for (const auto& [k, v] : s.mean_info) std::printf(" %16.3f", v);
      for (const auto& [k, t] : s.to_teacher) std::printf(" %24.4f %24.4f", t.rms, t.active_rms);
      std::printf("\n");
      std::fflush(stdout);
      if (out.is_open()) {
        out << e.name << "," << episodes << "," << first_seed << "," << s.mean_return << ","
            << s.std_return << "," << s.mean_steps << "," << s.terminated;
        for (const auto& [k, v] : s.mean_info) out << "," << v;
        for (const auto& [k, t] : s.to_teacher) {
          out << "," << t.rms << "," << t.active_rms << "," << t.active_steps;
        }
        out << "\n";
      }
    }
  } catch (const std::exception& e) {
    std::cerr << "syndds_evaluate: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
