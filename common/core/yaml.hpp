#pragma once
// Strict YAML reading: every error names file:line:column and the dotted key path, unknown
// keys are errors, numbers must be finite. Readers of config structs use MapReader:
//
//   MapReader m(node);
//   cfg.step_s = m.get<double>("step_s");          // required
//   cfg.realtime = m.get_or("realtime", false);     // optional with default
//   m.finish();                                     // any key not asked for is an error
#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.hpp"

namespace syndds {

class YamlNode {
 public:
  /// Parses a file; syntax errors become ConfigError with file:line:column.
  static YamlNode load_file(const std::string& file);
  /// Parses text; `name` stands for the file name in messages.
  static YamlNode load_string(const std::string& text, const std::string& name);

  YamlNode(YAML::Node node, std::shared_ptr<const std::string> file, std::string path);

  const std::string& file() const { return *file_; }
  /// Dotted key path from the document root, e.g. "vehicles[1].controller.lookahead_m".
  const std::string& path() const { return path_; }
  /// "file:line:column" of this node (1-based).
  std::string where() const;
  [[noreturn]] void fail(const std::string& message) const;

  bool is_map() const { return node_.IsMap(); }
  bool is_sequence() const { return node_.IsSequence(); }
  bool is_scalar() const { return node_.IsScalar(); }
  bool is_null() const { return node_.IsNull(); }

  std::size_t size() const;                         // sequence length (fails if not a sequence)
  YamlNode operator[](std::size_t index) const;     // sequence element
  std::vector<YamlNode> elements() const;           // all sequence elements

  double as_double() const;  // finite number
  std::int64_t as_int() const;
  bool as_bool() const;
  std::string as_string() const;
  /// A sequence of exactly `n` finite numbers (n = 0: any length).
  std::vector<double> as_doubles(std::size_t n = 0) const;

  template <typename T>
  T as() const;

  const YAML::Node& raw() const { return node_; }

 private:
  friend class MapReader;
  YAML::Node node_;
  std::shared_ptr<const std::string> file_;
  std::string path_;
};

template <>
inline double YamlNode::as<double>() const { return as_double(); }
template <>
inline std::int64_t YamlNode::as<std::int64_t>() const { return as_int(); }
template <>
inline int YamlNode::as<int>() const { return static_cast<int>(as_int()); }
template <>
inline bool YamlNode::as<bool>() const { return as_bool(); }
template <>
inline std::string YamlNode::as<std::string>() const { return as_string(); }

/// Reads a YAML mapping, remembering which keys were asked for so finish() can reject the rest.
class MapReader {
 public:
  explicit MapReader(const YamlNode& node);

  const YamlNode& node() const { return node_; }
  bool has(std::string_view key) const;
  std::optional<YamlNode> optional(std::string_view key);
  YamlNode required(std::string_view key);

  template <typename T>
  T get(std::string_view key) {
    return required(key).as<T>();
  }
  template <typename T>
  T get_or(std::string_view key, T fallback) {
    auto n = optional(key);
    return n ? n->as<T>() : fallback;
  }
  /// Number with bounds checked: lo <= v <= hi (messages name the key).
  double number(std::string_view key, std::optional<double> fallback, double lo, double hi);
  /// Strictly positive number.
  double positive(std::string_view key, std::optional<double> fallback);
  /// One of the allowed strings.
  std::string choice(std::string_view key, std::optional<std::string> fallback,
                     const std::vector<std::string>& allowed);

  /// Fails on the first key that was never asked for, naming it and the known keys.
  void finish() const;

 private:
  YamlNode child(const YAML::Node& key, const YAML::Node& value) const;
  YamlNode node_;
  std::set<std::string, std::less<>> asked_;
};

}  // namespace syndds
