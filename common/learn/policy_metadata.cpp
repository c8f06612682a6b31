#include "learn/policy_metadata.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "core/yaml.hpp"

namespace fs = std::filesystem;

namespace syndds::learn {
namespace {

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

}  // namespace

std::string policy_sidecar_path(const std::string& policy_file) {
  return fs::path(policy_file).replace_extension(".json").string();
}

void write_policy_sidecar(const std::string& policy_file, const PolicyMetadata& metadata) {
  const std::string path = policy_sidecar_path(policy_file), tmp = path + ".tmp";
  std::string text = "{";
  bool first = true;
  for (const auto& [k, v] : metadata) {
    text += (first ? "\n  " : ",\n  ") + json_string(k) + ": " + json_string(v);
    first = false;
  }
  text += "\n}\n";
  std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
  if (!out || !(out << text) || !out.flush()) throw std::runtime_error("cannot write " + tmp);
  out.close();
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    throw std::runtime_error("cannot rename " + tmp + " to " + path);
  }
}

std::optional<PolicyMetadata> read_policy_sidecar(const std::string& policy_file) {
  const std::string path = policy_sidecar_path(policy_file);
  if (!fs::exists(path)) return std::nullopt;
  // JSON is YAML: the project's YAML reader names the file and line of a bad entry.
  const YamlNode root = YamlNode::load_file(path);
  if (!root.is_map()) throw std::runtime_error(path + ": expected a JSON object of strings");
  PolicyMetadata m;
  for (const auto& kv : root.raw()) {
    const std::string key = kv.first.as<std::string>();
    if (!kv.second.IsScalar()) {
      throw std::runtime_error(path + ": " + key + ": expected a string");
    }
    m[key] = kv.second.as<std::string>();
  }
  return m;
}

}  // namespace syndds::learn
