#include "learn/ppo/normalizer.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace syndds::learn::ppo {
namespace {

torch::Tensor to_tensor(const std::vector<double>& v) {
  return torch::tensor(at::ArrayRef<double>(v), torch::kFloat64);
}

std::vector<double> from_tensor(const torch::Tensor& t) {
  const torch::Tensor c = t.contiguous().to(torch::kFloat64);
  return {c.data_ptr<double>(), c.data_ptr<double>() + c.numel()};
}

}  // namespace

RunningNormalizer::RunningNormalizer(int size)
    : mean_(static_cast<std::size_t>(size), 0.0), var_(static_cast<std::size_t>(size), 1.0) {}

void RunningNormalizer::update(const std::vector<std::span<const float>>& batch) {
  if (batch.empty()) return;
  const std::size_t d = mean_.size();
  const auto n = static_cast<double>(batch.size());
  for (std::size_t j = 0; j < d; ++j) {
    double m = 0.0;
    for (const auto& x : batch) {
      if (x.size() != d) {
        throw std::invalid_argument("RunningNormalizer: observation of " +
                                    std::to_string(x.size()) + " values, expected " +
                                    std::to_string(d));
      }
      m += x[j];
    }
    m /= n;
    double m2 = 0.0;
    for (const auto& x : batch) m2 += (x[j] - m) * (x[j] - m);
    // Merge (count_, mean_, var_) with (n, m, m2 / n).
    const double total = count_ + n;
    const double delta = m - mean_[j];
    const double merged_m2 =
        var_[j] * count_ + m2 + delta * delta * count_ * n / total;
    mean_[j] += delta * n / total;
    var_[j] = merged_m2 / total;
  }
  count_ += n;
}

std::vector<float> RunningNormalizer::normalize(std::span<const float> x) const {
  if (x.size() != mean_.size()) {
    throw std::invalid_argument("RunningNormalizer: observation of " + std::to_string(x.size()) +
                                " values, expected " + std::to_string(mean_.size()));
  }
  std::vector<float> out(x.size());
  for (std::size_t j = 0; j < x.size(); ++j) {
    const double z = (x[j] - mean_[j]) / std::sqrt(var_[j] + kEpsilon);
    out[j] = static_cast<float>(std::clamp(z, -kClip, kClip));
  }
  return out;
}

void RunningNormalizer::save(torch::serialize::OutputArchive& archive) const {
  archive.write("mean", to_tensor(mean_));
  archive.write("variance", to_tensor(var_));
  archive.write("count", torch::tensor(count_, torch::kFloat64));
}

void RunningNormalizer::load(torch::serialize::InputArchive& archive) {
  torch::Tensor m, v, c;
  archive.read("mean", m);
  archive.read("variance", v);
  archive.read("count", c);
  mean_ = from_tensor(m);
  var_ = from_tensor(v);
  count_ = c.item<double>();
}

}  // namespace syndds::learn::ppo
