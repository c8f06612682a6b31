#pragma once
// Environments by name, for programs (syndds_train) that are told which one to use on the
// command line: one place that knows every environment and its options.
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "learn/convoy_env.hpp"
#include "learn/env.hpp"

namespace syndds::learn {

/// Options of an environment, as text (name -> value), e.g. from `--env-option key=value`.
using EnvOptions = std::map<std::string, std::string>;

/// Options from KEY=VALUE texts (`--env-option`); std::invalid_argument naming a text without
/// '=' or a key given twice.
EnvOptions parse_env_options(const std::vector<std::string>& key_values);

/// Options as one line, "KEY=VALUE KEY=VALUE" sorted by key (a policy file's env_options),
/// and back (std::invalid_argument as parse_env_options).
std::string env_options_line(const EnvOptions& options);
EnvOptions parse_env_options_line(const std::string& line);

/// The convoy_follow environment's options from text (std::invalid_argument naming the option).
ConvoyEnvOptions convoy_env_options(const EnvOptions& options);

/// The names make_env knows, sorted.
std::vector<std::string> env_names();

/// A factory of environment `name` with `options`. Throws std::invalid_argument naming the
/// unknown environment or the option it does not take (or whose value is bad); the options are
/// checked here, before any environment is made.
EnvFactory env_factory(const std::string& name, const EnvOptions& options = {});

/// One environment: env_factory(name, options)().
std::unique_ptr<Env> make_env(const std::string& name, const EnvOptions& options = {});

}  // namespace syndds::learn
