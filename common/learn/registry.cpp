#include "learn/registry.hpp"

#include <stdexcept>

#include "learn/double_integrator.hpp"

namespace syndds::learn {
namespace {

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

void no_options(const std::string& name, const EnvOptions& options) {
  if (!options.empty()) {
    throw std::invalid_argument("environment " + name + " takes no options (got " +
                                options.begin()->first + ")");
  }
}

}  // namespace

std::vector<std::string> env_names() { return {"double_integrator"}; }

EnvFactory env_factory(const std::string& name, const EnvOptions& options) {
  if (name == "double_integrator") {
    no_options(name, options);
    return [] { return std::make_unique<DoubleIntegrator>(); };
  }
  throw std::invalid_argument("unknown environment " + name + " (known: " + joined(env_names()) +
                              ")");
}

std::unique_ptr<Env> make_env(const std::string& name, const EnvOptions& options) {
  return env_factory(name, options)();
}

}  // namespace syndds::learn
