#include "learn/ppo/policy.hpp"

#include <ATen/CPUGeneratorImpl.h>
#include <torch/torch.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "learn/ppo/networks.hpp"
#include "learn/ppo/normalizer.hpp"
#include "learn/ppo/policy_file.hpp"
#include "learn/ppo/trainer.hpp"

namespace syndds::learn::ppo {
namespace {

torch::Tensor floats(const std::vector<float>& v) {
  return torch::tensor(at::ArrayRef<float>(v), torch::kFloat32);
}

std::vector<float> floats(const torch::Tensor& t) {
  const torch::Tensor c = t.contiguous().to(torch::kFloat32);
  return {c.data_ptr<float>(), c.data_ptr<float>() + c.numel()};
}

}  // namespace

torch::Tensor read_tensor(torch::serialize::InputArchive& archive, const std::string& key) {
  torch::Tensor t;
  archive.read(key, t);
  return t;
}

void save_policy_file(const std::string& path, const ActorCritic& model,
                      const RunningNormalizer& normalizer, const ObservationSpace& observations,
                      const Box& actions, const PolicyMetadata& metadata) {
  torch::serialize::OutputArchive archive, m, n;
  model.save(m);
  normalizer.save(n);
  archive.write("model", m);
  archive.write("normalizer", n);
  archive.write("network", c10::IValue(model.kind()));
  archive.write("observation_low", floats(observations.vector.low));
  archive.write("observation_high", floats(observations.vector.high));
  const ImageSpec image = observations.image.value_or(ImageSpec{});
  archive.write("image", torch::tensor({static_cast<std::int64_t>(observations.image.has_value()),
                                        static_cast<std::int64_t>(image.width),
                                        static_cast<std::int64_t>(image.height),
                                        static_cast<std::int64_t>(image.channels)}));
  archive.write("action_low", floats(actions.low));
  archive.write("action_high", floats(actions.high));
  if (!actions.explore.empty()) {  // written only when some dimension is not explored
    std::vector<float> explore;
    for (const bool e : actions.explore) explore.push_back(e ? 1.0f : 0.0f);
    archive.write("action_explore", floats(explore));
  }
  std::string lines;  // key=value per line
  for (const auto& [k, v] : metadata) {
    if (k.find_first_of("=\n") != std::string::npos || v.find('\n') != std::string::npos) {
      throw std::invalid_argument("policy metadata: '" + k + "' has a newline or '=' in it");
    }
    lines += k + "=" + v + "\n";
  }
  if (!lines.empty()) archive.write("metadata", c10::IValue(lines));
  const std::string tmp = path + ".tmp";
  archive.save_to(tmp);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    throw std::runtime_error("cannot rename " + tmp + " to " + path);
  }
}

void Trainer::save_policy(const std::string& path, const PolicyMetadata& metadata) const {
  save_policy_file(path, *model_, normalizer_, observation_space_, action_space_, metadata);
}

}  // namespace syndds::learn::ppo

namespace syndds::learn {

struct Policy::Net {
  std::shared_ptr<ppo::ActorCritic> model;
  ppo::RunningNormalizer normalizer;
  at::Generator generator;
};

void Policy::load(const std::string& path) {
  torch::serialize::InputArchive archive;
  if (!std::ifstream(path)) throw std::runtime_error("cannot read " + path);
  try {
    archive.load_from(path);
  } catch (const c10::Error& e) {  // its what() carries a stack trace: the message alone
    throw std::runtime_error(path + " is not a policy file: " + e.what_without_backtrace());
  }
  observations_.vector.low = ppo::floats(ppo::read_tensor(archive, "observation_low"));
  observations_.vector.high = ppo::floats(ppo::read_tensor(archive, "observation_high"));
  observations_.vector.names.clear();
  const torch::Tensor t = ppo::read_tensor(archive, "image");
  if (t[0].item<std::int64_t>() != 0) {
    observations_.image = ImageSpec{static_cast<int>(t[1].item<std::int64_t>()),
                                    static_cast<int>(t[2].item<std::int64_t>()),
                                    static_cast<int>(t[3].item<std::int64_t>())};
  } else {
    observations_.image.reset();
  }
  actions_.low = ppo::floats(ppo::read_tensor(archive, "action_low"));
  actions_.high = ppo::floats(ppo::read_tensor(archive, "action_high"));
  actions_.names.clear();
  actions_.explore.clear();
  torch::Tensor explore;
  if (archive.try_read("action_explore", explore)) {
    for (const float e : ppo::floats(explore)) actions_.explore.push_back(e != 0.0f);
  }
  metadata_.clear();
  c10::IValue meta;
  if (archive.try_read("metadata", meta)) {
    const std::string& text = meta.toStringRef();
    std::size_t at = 0;
    while (at < text.size()) {
      const std::size_t end = text.find('\n', at);
      const std::string line = text.substr(at, end - at);
      const std::size_t eq = line.find('=');
      if (eq != std::string::npos) metadata_[line.substr(0, eq)] = line.substr(eq + 1);
      at = end == std::string::npos ? text.size() : end + 1;
    }
  }
  c10::IValue network;
  archive.read("network", network);
  auto net = std::make_shared<Net>();
  net->model = ppo::make_actor_critic(network.toStringRef(), observations_, actions_);
  torch::serialize::InputArchive m, n;
  archive.read("model", m);
  archive.read("normalizer", n);
  net->model->load(m);
  net->model->eval();
  net->normalizer.load(n);
  net->generator = net_ ? net_->generator : at::make_generator<at::CPUGeneratorImpl>(0);
  net_ = std::move(net);
}

void Policy::seed(std::uint64_t seed) {
  auto net = net_ ? std::make_shared<Net>(*net_) : std::make_shared<Net>();
  net->generator = at::make_generator<at::CPUGeneratorImpl>(seed);
  net_ = std::move(net);
}

std::vector<float> Policy::act(const Observation& observation, bool deterministic) {
  if (!net_ || !net_->model) throw std::logic_error("Policy::act before load");
  const std::vector<float> z = net_->normalizer.normalize(observation.vector);
  const torch::Tensor vec =
      torch::tensor(at::ArrayRef<float>(z), torch::kFloat32).reshape({1, -1});
  torch::Tensor img;
  if (observations_.image) img = ppo::image_batch({&observation.image}, *observations_.image);
  torch::NoGradGuard no_grad;
  const ppo::ActorCriticOutput out = net_->model->forward(vec, img);
  torch::Tensor a = out.mean;
  if (!deterministic) {
    torch::Tensor noise = at::normal(0.0, 1.0, a.sizes(), net_->generator, torch::kFloat32);
    for (std::size_t j = 0; j < actions_.size(); ++j) {
      if (!actions_.explored(j)) noise[0][static_cast<std::int64_t>(j)] = 0.0f;
    }
    a = a + torch::exp(net_->model->log_std) * noise;
  }
  std::vector<float> action = ppo::floats(a);
  for (std::size_t j = 0; j < action.size(); ++j) {
    action[j] = std::clamp(action[j], actions_.low[j], actions_.high[j]);
  }
  return action;
}

}  // namespace syndds::learn
