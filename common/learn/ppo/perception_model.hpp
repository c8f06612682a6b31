#pragma once
// A fitted perception network (docs/learning.md, "Perception") for inference: the file
// syndds_train --perceive-steps writes (the network's parameters, its image size and outputs).
// The network lives behind this interface (perception.cpp), so its users compile without
// libtorch's headers; fitting and saving one are in perception.hpp.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "learn/env.hpp"

namespace syndds::learn::ppo {

class PerceptionNet;

class PerceptionModel {
 public:
  /// Throws std::runtime_error naming `path` when it is not a perception file.
  static PerceptionModel load(const std::string& path);
  static void save(const std::string& path, PerceptionNet& net, const ImageSpec& image);
  /// The network's outputs for one image of the model's size (std::invalid_argument
  /// otherwise). Safe to call from several threads at once.
  std::vector<float> read(const std::vector<std::uint8_t>& image) const;
  const ImageSpec& image() const { return image_; }
  int outputs() const { return outputs_; }

 private:
  std::shared_ptr<PerceptionNet> net_;
  ImageSpec image_;
  int outputs_ = 0;
};

}  // namespace syndds::learn::ppo
