#include "learn/registry.hpp"

#include <charconv>
#include <cmath>
#include <set>
#include <stdexcept>

#include "learn/convoy_env.hpp"
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

// Reads option values: every key must be known, every value parse, and be in range.
class OptionReader {
 public:
  OptionReader(std::string env, const EnvOptions& options) : env_(std::move(env)), options_(options) {}

  std::string choice(const std::string& key, const std::string& fallback,
                     const std::vector<std::string>& allowed) {
    const std::string v = raw(key, fallback);
    for (const auto& a : allowed) {
      if (v == a) return v;
    }
    fail(key, "'" + v + "' is not one of " + joined(allowed));
  }
  bool flag(const std::string& key, bool fallback) {
    const std::string v = raw(key, fallback ? "true" : "false");
    if (v == "true" || v == "True" || v == "1") return true;
    if (v == "false" || v == "False" || v == "0") return false;
    fail(key, "'" + v + "' is not true or false");
  }
  double number(const std::string& key, double fallback, double lo, double hi) {
    const std::string v = raw(key, "");
    if (v.empty()) return fallback;
    double x = 0.0;
    const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
    if (ec != std::errc() || end != v.data() + v.size()) fail(key, "'" + v + "' is not a number");
    if (!(x >= lo && x <= hi)) {
      fail(key, "'" + v + "' is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    return x;
  }
  int whole(const std::string& key, int fallback, int lo, int hi) {
    const double x = number(key, fallback, lo, hi);
    if (x != std::floor(x)) fail(key, "'" + raw(key, "") + "' is not a whole number");
    return static_cast<int>(x);
  }
  /// Throws naming the first option that was never read.
  void finish() const {
    for (const auto& [k, v] : options_) {
      if (!read_.contains(k)) {
        throw std::invalid_argument("environment " + env_ + " has no option " + k);
      }
    }
  }

 private:
  std::string raw(const std::string& key, const std::string& fallback) {
    read_.insert(key);
    const auto it = options_.find(key);
    return it == options_.end() ? fallback : it->second;
  }
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw std::invalid_argument("environment " + env_ + ", option " + key + ": " + what);
  }

  std::string env_;
  const EnvOptions& options_;
  std::set<std::string> read_;
};

}  // namespace

ConvoyEnvOptions convoy_env_options(const EnvOptions& options) {
  OptionReader r("convoy_follow", options);
  ConvoyEnvOptions o;
  const std::string terrain = r.choice("terrain", "rigid", {"rigid", "scm_hard", "scm_soft"});
  o.terrain = terrain == "rigid"      ? ConvoyTerrain::rigid
              : terrain == "scm_hard" ? ConvoyTerrain::scm_hard
                                      : ConvoyTerrain::scm_soft;
  o.dynamics = r.choice("dynamics", "reduced", {"reduced", "full"}) == "full"
                   ? ConvoyDynamics::full
                   : ConvoyDynamics::reduced;
  o.camera = r.flag("camera", false);
  o.observation = parse_observation_kind(
      r.choice("observation", "paper",
               {"paper", "trail", "trail_action", "trail_ff", "trail_ff_memory"}));
  o.reward_kind = r.choice("reward", "paper", {"paper", "track"}) == "track"
                      ? ConvoyRewardKind::track
                      : ConvoyRewardKind::paper;
  o.reward.steer_change = r.number("steer_change", 0.0, 0.0, 10.0);
  o.steer_lag_s = r.number("steer_lag", 0.0, 0.0, 10.0);
  o.steering_residual = r.choice("steering", "command", {"command", "residual"}) == "residual";
  o.episode.leader_wobble_m = r.number("leader_wobble", 0.0, 0.0, 2.0);
  o.episode.chain_fraction = r.number("chain", 0.0, 0.0, 1.0);
  o.teacher_keep_clear_m = r.number("teacher_keep_clear", 0.0, 0.0, 10.0);
  o.teacher_steering_limit = r.number("teacher_steering_limit", 1.0, 1.0, 3.0);
  const std::string view = r.choice("teacher_view", "map", {"map", "camera", "ranges"});
  o.teacher_view_camera = view == "camera";
  o.teacher_view_ranges = view == "ranges";
  o.observe_keep_out = r.flag("observe_keep_out", false);
  o.random_ground_colour = r.choice("ground_colour", "fixed", {"fixed", "random"}) == "random";
  o.friction_min = r.number("friction_min", 0.0, 0.0, 0.8);
  o.start_hold_max_s = r.number("start_hold_max", 0.0, 0.0, 30.0);
  o.episode.kind = parse_episode_kind(r.choice("episodes", "paper", {"paper", "courses", "mixed"}));
  o.target_speed_mps = r.number("target_speed", o.target_speed_mps, 0.5, 20.0);
  o.target_speed_max_mps = r.number("target_speed_max", 0.0, 0.0, 20.0);
  if (o.target_speed_max_mps > 0.0 && o.target_speed_max_mps < o.target_speed_mps) {
    throw std::invalid_argument("environment convoy_follow, option target_speed_max: below "
                                "target_speed");
  }
  if (o.random_ground_colour && o.terrain != ConvoyTerrain::rigid) {
    throw std::invalid_argument("environment convoy_follow, option ground_colour: random is for "
                                "terrain=rigid (the soils keep their own look)");
  }
  if (o.friction_min > 0.0 && o.terrain != ConvoyTerrain::rigid) {
    throw std::invalid_argument("environment convoy_follow, option friction_min: is for "
                                "terrain=rigid (the soils have their own shear strength)");
  }
  if (o.steering_residual && !has_feedforward(o.observation)) {
    throw std::invalid_argument("environment convoy_follow, option steering: residual needs an "
                                "observation with the feed-forward steering (trail_ff, "
                                "trail_ff_memory)");
  }
  if ((o.teacher_view_camera || o.teacher_view_ranges) && !o.camera) {
    throw std::invalid_argument("environment convoy_follow, option teacher_view: " +
                                std::string(o.teacher_view_camera ? "camera" : "ranges") +
                                " needs camera=true (the teacher sees what that camera sees)");
  }
  if (o.observe_keep_out && !(o.teacher_keep_clear_m > 0.0)) {
    throw std::invalid_argument("environment convoy_follow, option observe_keep_out: needs "
                                "teacher_keep_clear > 0 (the shift observed is that map's)");
  }
  o.frames_per_step = r.whole("frames_per_step", o.frames_per_step, 1, 100);
  o.max_steps = r.whole("max_steps", o.max_steps, 1, 100000);
  r.finish();
  return o;
}

std::string env_options_line(const EnvOptions& options) {
  std::string out;
  for (const auto& [k, v] : options) out += (out.empty() ? "" : " ") + k + "=" + v;
  return out;
}

EnvOptions parse_env_options_line(const std::string& line) {
  std::vector<std::string> parts;
  std::size_t at = 0;
  while (at < line.size()) {
    const std::size_t end = line.find(' ', at);
    const std::string part = line.substr(at, end - at);
    if (!part.empty()) parts.push_back(part);
    at = end == std::string::npos ? line.size() : end + 1;
  }
  return parse_env_options(parts);
}

EnvOptions parse_env_options(const std::vector<std::string>& key_values) {
  EnvOptions out;
  for (const auto& kv : key_values) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos || eq == 0) {
      throw std::invalid_argument("'" + kv + "': expected KEY=VALUE");
    }
    if (!out.emplace(kv.substr(0, eq), kv.substr(eq + 1)).second) {
      throw std::invalid_argument("'" + kv + "': " + kv.substr(0, eq) + " given twice");
    }
  }
  return out;
}

std::vector<std::string> env_names() { return {"convoy_follow", "double_integrator"}; }

EnvFactory env_factory(const std::string& name, const EnvOptions& options) {
  if (name == "convoy_follow") {
    const ConvoyEnvOptions o = convoy_env_options(options);
    return [o] { return make_convoy_env(o); };
  }
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
