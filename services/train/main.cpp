// syndds_train: PPO on one of the learning environments (docs/learning.md): one progress line
// per update, DIR/training.csv, DIR/checkpoint.pt (rewritten after every update; --resume
// continues from it bit for bit), DIR/policy.pt (for learn::Policy) and, when Debian's
// matplotlib is there, DIR/training_curve.png (tools/training_curve.py).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>

#include "learn/convoy_env.hpp"
#include "learn/ppo/perception.hpp"
#include "learn/ppo/trainer.hpp"
#include "learn/registry.hpp"

using namespace syndds;
namespace fs = std::filesystem;

namespace {

constexpr const char* kHeader =
    "update,interactions,episodes,mean_return,moving_average_return,policy_loss,value_loss,"
    "entropy,approx_kl,clip_fraction,wall_s,imitation_weight,imitation_loss";

std::string number(double v) {
  if (std::isnan(v)) return "nan";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

/// Keeps the header and the rows of updates <= `updates` of an existing training.csv (a resumed
/// run rewrites what came after its checkpoint).
std::string kept_rows(const fs::path& csv, int updates) {
  std::ifstream in(csv);
  std::string line, out = std::string(kHeader) + "\n";
  std::getline(in, line);
  while (std::getline(in, line)) {
    if (!line.empty() && std::stoi(line.substr(0, line.find(','))) <= updates) out += line + "\n";
  }
  return out;
}

std::string duration(double s) {
  const long t = std::lround(s);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, t / 60 % 60, t % 60);
  return buf;
}

/// --perceive-steps: the perception fit alone (learn::ppo::fit_perception), its epochs to
/// DIR/perception.csv and the network to DIR/perception.pt.
int fit_perception(const learn::EnvFactory& factory, const learn::ppo::TrainerOptions& options,
                   const learn::ppo::PerceptionOptions& perceive, const fs::path& dir) {
  const auto env = factory();
  const auto image = env->observation_space().image;
  if (!image) {
    std::cerr << "syndds_train: --perceive-steps: the environment's observations have no image "
                 "(convoy_follow needs --env-option camera=true)\n";
    return 1;
  }
  const fs::path csv_path = dir / "perception.csv", net_path = dir / "perception.pt";
  if (fs::exists(net_path)) {
    std::cerr << "syndds_train: " << net_path.string() << " exists: choose another --output\n";
    return 1;
  }
  torch::manual_seed(options.seed);
  torch::set_num_threads(options.torch_threads);
  env->reset(learn::episode_seed(options.seed, 0, 0));
  const auto outputs = static_cast<int>(env->perception_target().size());
  if (outputs == 0) {
    std::cerr << "syndds_train: --perceive-steps: the environment has no perception target\n";
    return 1;
  }
  auto net = std::make_shared<learn::ppo::PerceptionNet>(*image, outputs);
  learn::VectorEnv envs(factory, options.copies, options.threads);
  at::Generator generator = at::make_generator<at::CPUGeneratorImpl>(options.seed);
  std::ofstream csv(csv_path, std::ios::binary | std::ios::trunc);
  csv << "epoch,train_rms,holdout_rms,holdout_seen_rms\n";
  std::printf("perception fit: %lld interactions driven by the expert, %d outputs, %d epochs\n",
              static_cast<long long>(perceive.steps), outputs, perceive.epochs);
  std::fflush(stdout);
  const learn::ppo::PerceptionStats s = learn::ppo::fit_perception(
      envs, options.seed, perceive, *net, generator, [&](const learn::ppo::PerceptionEpoch& e) {
        std::printf("perception epoch %d/%d  RMS training %s, held out %s, held out where "
                    "something is seen %s\n",
                    e.epoch, perceive.epochs, number(e.train_rms).c_str(),
                    number(e.holdout_rms).c_str(), number(e.holdout_seen_rms).c_str());
        std::fflush(stdout);
        csv << e.epoch << ',' << number(e.train_rms) << ',' << number(e.holdout_rms) << ','
            << number(e.holdout_seen_rms) << '\n';
        csv.flush();
      });
  if (!csv) {
    std::cerr << "syndds_train: cannot write " << csv_path.string() << "\n";
    return 1;
  }
  learn::ppo::PerceptionModel::save(net_path.string(), *net, *image);
  std::printf("perception fit on %lld images (%lld more held out; %lld episodes) in %s collecting "
              "and %s fitting; held out, an image-blind network (the training mean): RMS %s, "
              "%s where something is seen (%s of the values)\nwrote %s, %s\n",
              static_cast<long long>(s.train_samples), static_cast<long long>(s.holdout_samples),
              static_cast<long long>(s.episodes), duration(s.collect_s).c_str(),
              duration(s.learn_s).c_str(), number(s.holdout_mean_rms).c_str(),
              number(s.holdout_mean_seen_rms).c_str(), number(s.seen_share).c_str(),
              csv_path.string().c_str(), net_path.string().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"syndds train: PPO on a learning environment (docs/learning.md)"};
  std::string env_name;
  std::vector<std::string> env_option_args;
  int updates = 100;
  std::string output = "training";
  bool resume = false;
  learn::ppo::TrainerOptions options;
  auto& ppo = options.ppo;
  app.add_option("--env", env_name, "Environment (" + [] {
                   std::string s;
                   for (const auto& n : learn::env_names()) s += (s.empty() ? "" : ", ") + n;
                   return s;
                 }() + ")")
      ->required();
  app.add_option("--env-option", env_option_args, "Environment option KEY=VALUE (repeatable)");
  app.add_option("--updates", updates,
                 "Updates in all (a resumed run goes on to this count). 0 with --init-from "
                 "writes that policy's network under this run's environment options and "
                 "metadata (e.g. to attach --perception)")
      ->check(CLI::Range(0, 1 << 30))
      ->capture_default_str();
  app.add_option("--steps-per-update", ppo.steps_per_update,
                 "Interactions per update, summed over the copies")
      ->check(CLI::Range(1, 1 << 30))
      ->capture_default_str();
  app.add_option("--copies", options.copies, "Environment copies")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  app.add_option("--threads", options.threads, "Threads stepping the copies")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--torch-threads", options.torch_threads,
                 "Threads of libtorch's operators (the learning phase; the environment copies "
                 "are idle then). A run is reproducible for a given number")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--seed", options.seed, "Seed of the networks, sampling and episodes")
      ->capture_default_str();
  app.add_option("--network", options.network, "Actor-critic network")
      ->check(CLI::IsMember({"auto", "mlp", "fusion", "residual_fusion"}))
      ->capture_default_str();
  app.add_option("--epochs", ppo.epochs, "Passes over each rollout")
      ->check(CLI::Range(1, 1 << 30))
      ->capture_default_str();
  app.add_option("--minibatch", ppo.minibatch, "Minibatch size")
      ->check(CLI::Range(2, 1 << 20))
      ->capture_default_str();
  app.add_option("--learning-rate", ppo.learning_rate, "Adam's learning rate")
      ->check(CLI::Range(1e-9, 1.0))
      ->capture_default_str();
  app.add_option("--entropy-coef", ppo.entropy_coef, "Weight of the entropy bonus")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--imitation-weight", options.imitation_weight,
                 "Weight of imitating the environment's expert action (convoy_follow with a trail "
                 "observation: the classical follower's command) in the loss; 0: PPO alone")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--imitation-updates", options.imitation_updates,
                 "The imitation weight falls linearly to 0 over this many updates (0: constant)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--output", output, "Directory of training.csv, checkpoint.pt, policy.pt")
      ->capture_default_str();
  app.add_flag("--resume", resume, "Continue from OUTPUT/checkpoint.pt");
  std::string init_from;
  app.add_option("--init-from", init_from,
                 "Start from this policy.pt of an earlier stage (curriculum, e.g. the reduced "
                 "model's policy for training on the full model)")
      ->excludes("--resume");
  learn::ppo::CloneOptions clone;
  app.add_option("--clone-steps", clone.steps,
                 "Behaviour cloning before the first update: interactions driven by the "
                 "environment's expert (summed over the copies) whose expert actions the "
                 "policy's mean is fitted to; 0: none. DIR/clone.csv gets the RMS distance to "
                 "the expert per action and epoch, on the training and the held-out episodes")
      ->check(CLI::Range(std::int64_t{0}, std::int64_t{1} << 40))
      ->capture_default_str();
  app.add_option("--clone-iterations", clone.iterations,
                 "DAgger: iterations of --clone-steps each; the first is driven by the expert, "
                 "the later ones by the policy (its mean action), every state labelled by the "
                 "expert, and each refits on all the data so far")
      ->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  app.add_option("--clone-epochs", clone.epochs, "Passes over the cloning data per iteration")
      ->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  app.add_option("--clone-minibatch", clone.minibatch, "Minibatch size of the cloning")
      ->check(CLI::Range(2, 1 << 20))
      ->capture_default_str();
  app.add_option("--clone-holdout", clone.holdout,
                 "Share of each copy's cloning episodes held out (measured, never fitted)")
      ->check(CLI::Range(0.0, 0.99))
      ->capture_default_str();
  app.add_option("--clone-colour-jitter", clone.colour_jitter,
                 "Cloning's image augmentation: each training image's channels scaled by "
                 "factors in [1-J, 1+J] and offset by up to 128 J; 0: the images as rendered")
      ->check(CLI::Range(0.0, 0.99))
      ->capture_default_str();
  learn::ppo::PerceptionOptions perceive;
  app.add_option("--perceive-steps", perceive.steps,
                 "Instead of a policy, fit a camera network to the environment's perception "
                 "target (convoy_follow with camera=true: the obstacles' ranges across the "
                 "camera's view) on images from this many interactions driven by the expert; "
                 "writes DIR/perception.csv and DIR/perception.pt (docs/learning.md, "
                 "\"Perception\")")
      ->check(CLI::Range(std::int64_t{0}, std::int64_t{1} << 40))
      ->capture_default_str();
  app.add_option("--perceive-epochs", perceive.epochs, "Passes over the perception data")
      ->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  app.add_option("--perceive-minibatch", perceive.minibatch, "Minibatch size of the perception fit")
      ->check(CLI::Range(2, 1 << 20))
      ->capture_default_str();
  app.add_option("--perceive-holdout", perceive.holdout,
                 "Share of each copy's perception episodes held out (measured, never fitted)")
      ->check(CLI::Range(0.0, 0.99))
      ->capture_default_str();
  app.add_option("--perceive-learning-rate", perceive.learning_rate,
                 "Adam's learning rate in the perception fit")
      ->check(CLI::Range(1e-9, 1.0))
      ->capture_default_str();
  app.add_option("--perceive-colour-jitter", perceive.colour_jitter,
                 "As --clone-colour-jitter, for the perception fit")
      ->check(CLI::Range(0.0, 0.99))
      ->capture_default_str();
  std::string perception_file;
  app.add_option("--perception", perception_file,
                 "convoy_follow with observe_keep_out and teacher_view=ranges: the perception "
                 "network (--perceive-steps' perception.pt) a controller driving with this policy "
                 "reads the ranges with; copied beside policy.pt and named in its metadata. "
                 "Training itself reads the ground-truth ranges");
  CLI11_PARSE(app, argc, argv);
  if (perceive.steps > 0 && (resume || clone.steps > 0 || !init_from.empty())) {
    std::cerr << "syndds_train: --perceive-steps fits a perception network only: not with "
                 "--resume, --clone-steps or --init-from\n";
    return 1;
  }
  if (updates == 0 && clone.steps == 0 && perceive.steps == 0 && init_from.empty()) {
    std::cerr << "syndds_train: --updates 0 needs --clone-steps, --perceive-steps or "
                 "--init-from (nothing to train or write)\n";
    return 1;
  }

  learn::EnvOptions env_options;
  try {
    env_options = learn::parse_env_options(env_option_args);
  } catch (const std::invalid_argument& e) {
    std::cerr << "syndds_train: --env-option " << e.what() << "\n";
    return 1;
  }
  try {
    const fs::path dir(output);
    const fs::path checkpoint = dir / "checkpoint.pt", csv = dir / "training.csv";
    const auto names = learn::env_names();
    if (std::find(names.begin(), names.end(), env_name) == names.end()) {
      std::cerr << "syndds_train: --env: unknown environment " << env_name << "\n";
      return 1;
    }
    learn::EnvFactory factory;
    try {
      factory = learn::env_factory(env_name, env_options);
    } catch (const std::invalid_argument& e) {
      std::cerr << "syndds_train: --env-option: " << e.what() << "\n";
      return 1;
    }
    if ((options.network == "fusion" || options.network == "residual_fusion") &&
        !factory()->observation_space().image) {
      std::cerr << "syndds_train: --network " << options.network << ": " << env_name
                << "'s observations have no image\n";
      return 1;
    }
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
      std::cerr << "syndds_train: cannot create --output " << output << ": " << ec.message()
                << "\n";
      return 1;
    }
    if (perceive.steps > 0) return fit_perception(factory, options, perceive, dir);
    std::optional<learn::ppo::PerceptionModel> perception;
    if (!perception_file.empty()) {
      const learn::ConvoyEnvOptions o = learn::convoy_env_options(env_options);
      if (env_name != "convoy_follow" || !o.observe_keep_out || !o.teacher_view_ranges) {
        std::cerr << "syndds_train: --perception: for convoy_follow with observe_keep_out=true "
                     "and teacher_view=ranges\n";
        return 1;
      }
      try {
        perception = learn::ppo::PerceptionModel::load(perception_file);
      } catch (const std::runtime_error& e) {
        std::cerr << "syndds_train: --perception " << e.what() << "\n";
        return 1;
      }
      const auto image = factory()->observation_space().image;
      if (!image || image->bytes() != perception->image().bytes() ||
          perception->outputs() != learn::kPerceptionRays) {
        std::cerr << "syndds_train: --perception " << perception_file << ": reads another image "
                  << "or gives another number of ranges than this environment's camera\n";
        return 1;
      }
    } else if (env_name == "convoy_follow" &&
               learn::convoy_env_options(env_options).observe_keep_out &&
               learn::convoy_env_options(env_options).teacher_view_ranges) {
      std::printf("no --perception: a controller cannot drive with this policy (it needs the "
                  "network that reads the ranges)\n");
    }
    learn::ppo::Trainer trainer(factory, options);
    std::string rows = std::string(kHeader) + "\n";
    if (resume) {
      if (!fs::exists(checkpoint)) {
        std::cerr << "syndds_train: --resume: no " << checkpoint.string() << "\n";
        return 1;
      }
      trainer.load_checkpoint(checkpoint.string());
      rows = kept_rows(csv, trainer.updates());
      std::printf("resumed from %s after update %d (%lld interactions)\n",
                  checkpoint.string().c_str(), trainer.updates(),
                  static_cast<long long>(trainer.interactions()));
    } else if (fs::exists(checkpoint)) {
      std::cerr << "syndds_train: " << checkpoint.string()
                << " exists: pass --resume to continue it or choose another --output\n";
      return 1;
    }
    if (!init_from.empty()) {  // not with --resume (CLI11 refuses it)
      try {
        trainer.initialize_from_policy(init_from);
      } catch (const std::exception& e) {
        std::cerr << "syndds_train: --init-from " << init_from << ": " << e.what() << "\n";
        return 1;
      }
      std::printf("starting from the network of %s\n", init_from.c_str());
    }
    if (clone.steps > 0 && resume) {
      std::printf("--clone-steps: not on --resume (a run clones only before its first update)\n");
    } else if (clone.steps > 0) {
      const learn::Box actions = factory()->action_space();
      std::string header = "iteration,epoch";
      for (const char* kind : {"train_rms_", "holdout_rms_", "holdout_zero_rms_"}) {
        for (const auto& name : actions.names) header += "," + std::string(kind) + name;
      }
      std::ofstream clone_csv(dir / "clone.csv", std::ios::binary | std::ios::trunc);
      clone_csv << header << "\n";
      std::printf("cloning the expert: %d x %lld interactions, %d epochs each\n", clone.iterations,
                  static_cast<long long>(clone.steps), clone.epochs);
      std::fflush(stdout);
      const auto csv_field = [](const std::vector<double>& v, std::size_t i) {
        return v.empty() ? std::string("nan") : number(v[i]);
      };
      const learn::ppo::CloneStats cs = trainer.clone(clone, [&](const learn::ppo::CloneEpoch& e) {
        std::printf("clone iteration %d/%d epoch %d/%d  RMS to the expert, training / held out "
                    "(a policy of 0):",
                    e.iteration, clone.iterations, e.epoch, clone.epochs);
        clone_csv << e.iteration << ',' << e.epoch;
        for (std::size_t i = 0; i < actions.size(); ++i) {
          std::printf("  %s %s / %s (%s)", actions.names[i].c_str(), number(e.train_rms[i]).c_str(),
                      csv_field(e.holdout_rms, i).c_str(), csv_field(e.holdout_zero_rms, i).c_str());
          clone_csv << ',' << number(e.train_rms[i]);
        }
        for (std::size_t i = 0; i < actions.size(); ++i) clone_csv << ',' << csv_field(e.holdout_rms, i);
        for (std::size_t i = 0; i < actions.size(); ++i) {
          clone_csv << ',' << csv_field(e.holdout_zero_rms, i);
        }
        clone_csv << "\n";
        clone_csv.flush();
        std::printf("\n");
        std::fflush(stdout);
      });
      if (!clone_csv) {
        std::cerr << "syndds_train: cannot write " << (dir / "clone.csv").string() << "\n";
        return 1;
      }
      std::printf("cloned on %lld samples (%lld more held out; %lld episodes) in %s collecting and "
                  "%s fitting\n",
                  static_cast<long long>(cs.train_samples),
                  static_cast<long long>(cs.holdout_samples), static_cast<long long>(cs.episodes),
                  duration(cs.collect_s).c_str(), duration(cs.learn_s).c_str());
      trainer.save_checkpoint(checkpoint.string());
    }
    std::ofstream out(csv, std::ios::binary | std::ios::trunc);
    if (!out || !(out << rows) || !out.flush()) {
      std::cerr << "syndds_train: cannot write " << csv.string() << "\n";
      return 1;
    }
    std::printf("%s: %d interactions per update (%d copies), network %s, seed %llu\n",
                env_name.c_str(), trainer.rollout_size(), options.copies,
                trainer.model().kind().c_str(), static_cast<unsigned long long>(options.seed));
    const auto t0 = std::chrono::steady_clock::now();
    const int first = trainer.updates();
    while (trainer.updates() < updates) {
      const learn::ppo::UpdateStats s = trainer.update();
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      trainer.save_checkpoint(checkpoint.string());
      out << s.update << ',' << s.interactions << ',' << s.episodes << ',' << number(s.mean_return)
          << ',' << number(s.moving_average_return) << ',' << number(s.policy_loss) << ','
          << number(s.value_loss) << ',' << number(s.entropy) << ',' << number(s.approx_kl) << ','
          << number(s.clip_fraction) << ',' << number(wall) << ',' << number(s.imitation_weight)
          << ',' << number(s.imitation_loss) << '\n';
      out.flush();
      const double left = wall / (s.update - first) * (updates - s.update);
      std::printf("update %d/%d  interactions %lld  episodes %lld  mean return %s  (last %d: %s)"
                  "  time left %s\n",
                  s.update, updates, static_cast<long long>(s.interactions),
                  static_cast<long long>(s.episodes), number(s.mean_return).c_str(),
                  options.return_window, number(s.moving_average_return).c_str(),
                  duration(left).c_str());
      std::fflush(stdout);
    }
    if (!out) {
      std::cerr << "syndds_train: cannot write " << csv.string() << "\n";
      return 1;
    }
    trainer.save_checkpoint(checkpoint.string());
    learn::PolicyMetadata metadata{{"env", env_name},
                                   {"env_options", learn::env_options_line(env_options)},
                                   {"network", trainer.model().kind()},
                                   {"seed", std::to_string(options.seed)},
                                   {"updates", std::to_string(trainer.updates())},
                                   {"interactions", std::to_string(trainer.interactions())}};
    // Where the run started, kept by its checkpoints through a --resume.
    if (!trainer.init_from().empty()) metadata["init_from"] = trainer.init_from();
    if (clone.steps > 0) {
      metadata["clone"] = std::to_string(clone.iterations) + " x " +
                          std::to_string(clone.steps) + " interactions, " +
                          std::to_string(clone.epochs) + " epochs";
      if (clone.colour_jitter > 0.0) {
        metadata["clone"] += ", colour jitter " + number(clone.colour_jitter);
      }
    }
    if (options.imitation_weight > 0.0) {
      metadata["imitation"] = "weight " + number(options.imitation_weight) + " over " +
                              std::to_string(options.imitation_updates) + " updates";
    }
    if (env_name == "convoy_follow") {
      // The rig a vehicle driven by this policy needs (config/sensors/<rig>.yaml).
      metadata["sensors"] = factory()->observation_space().image ? "convoy_camera" : "convoy";
    }
    if (perception) {
      const fs::path copy = dir / "perception.pt";
      if (fs::absolute(perception_file) != fs::absolute(copy)) {
        fs::copy_file(perception_file, copy, fs::copy_options::overwrite_existing);
      }
      metadata["perception"] = copy.filename().string();
    }
    trainer.save_policy((dir / "policy.pt").string(), metadata);
    learn::write_policy_sidecar((dir / "policy.pt").string(), metadata);
    std::printf("wrote %s, %s, %s, %s\n", csv.string().c_str(), checkpoint.string().c_str(),
                (dir / "policy.pt").string().c_str(), (dir / "policy.json").string().c_str());
    const std::string script = std::string(SYNDDS_SOURCE_TOOLS_DIR) + "/training_curve.py";
    if (trainer.updates() == 0) {
      std::printf("no training_curve.png: no updates\n");
    } else if (std::system("/usr/bin/python3 -c 'import matplotlib' > /dev/null 2>&1") == 0) {
      const std::string cmd = "/usr/bin/python3 '" + script + "' '" + dir.string() + "'";
      if (std::system(cmd.c_str()) != 0) {
        std::cerr << "syndds_train: " << script << " failed\n";
        return 1;
      }
    } else {
      std::printf("no training_curve.png: install python3-matplotlib (launch_scripts/setup.sh "
                  "does), then run %s %s\n",
                  script.c_str(), dir.string().c_str());
    }
  } catch (const std::exception& e) {
    std::cerr << "syndds_train: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
