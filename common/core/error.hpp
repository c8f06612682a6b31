#pragma once
// Error types shared by every layer. Setup errors are exceptions caught in main();
// hot loops use status values instead.
#include <stdexcept>
#include <string>

namespace syndds {

/// Bad configuration (YAML file, command line): the message names file, line and key.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A protocol rule was broken (wrong frame, unknown member, malformed sample).
class ProtocolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace syndds
