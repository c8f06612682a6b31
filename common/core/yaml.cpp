#include "core/yaml.hpp"

#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>

namespace syndds {
namespace {

std::string mark_text(const std::string& file, const YAML::Mark& mark) {
  if (mark.is_null()) return file;
  return file + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}

std::string join(const std::set<std::string, std::less<>>& keys) {
  std::string out;
  for (const auto& k : keys) {
    if (!out.empty()) out += ", ";
    out += k;
  }
  return out;
}

}  // namespace

YamlNode YamlNode::load_file(const std::string& file) {
  std::ifstream in(file);
  if (!in) throw ConfigError(file + ": cannot open file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return load_string(buffer.str(), file);
}

YamlNode YamlNode::load_string(const std::string& text, const std::string& name) {
  auto file = std::make_shared<const std::string>(name);
  try {
    YAML::Node root = YAML::Load(text);
    return YamlNode(root, file, "");
  } catch (const YAML::ParserException& e) {
    throw ConfigError(mark_text(name, e.mark) + ": YAML syntax error: " + e.msg);
  }
}

YamlNode::YamlNode(YAML::Node node, std::shared_ptr<const std::string> file, std::string path)
    : node_(std::move(node)), file_(std::move(file)), path_(std::move(path)) {}

std::string YamlNode::where() const { return mark_text(*file_, node_.Mark()); }

void YamlNode::fail(const std::string& message) const {
  throw ConfigError(where() + ": " + (path_.empty() ? std::string("<document>") : path_) + ": " +
                    message);
}

std::size_t YamlNode::size() const {
  if (!node_.IsSequence()) fail("expected a list");
  return node_.size();
}

YamlNode YamlNode::operator[](std::size_t index) const {
  if (!node_.IsSequence()) fail("expected a list");
  if (index >= node_.size()) fail("list has no element " + std::to_string(index));
  return YamlNode(node_[index], file_, path_ + "[" + std::to_string(index) + "]");
}

std::vector<YamlNode> YamlNode::elements() const {
  std::vector<YamlNode> out;
  const std::size_t n = size();
  out.reserve(n);
  for (std::size_t i = 0; i < n; ++i) out.push_back((*this)[i]);
  return out;
}

double YamlNode::as_double() const {
  if (!node_.IsScalar()) fail("expected a number");
  const std::string text = node_.Scalar();
  double value = 0.0;
  try {
    std::size_t used = 0;
    value = std::stod(text, &used);
    if (used != text.size()) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    std::string lower;
    for (char c : text) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (lower.find("nan") != std::string::npos || lower.find("inf") != std::string::npos) {
      fail("expected a finite number, got '" + text + "'");
    }
    fail("expected a number, got '" + text + "'");
  }
  if (!std::isfinite(value)) fail("expected a finite number, got '" + text + "'");
  return value;
}

std::int64_t YamlNode::as_int() const {
  if (!node_.IsScalar()) fail("expected an integer");
  const std::string text = node_.Scalar();
  try {
    std::size_t used = 0;
    const long long value = std::stoll(text, &used);
    if (used != text.size()) throw std::invalid_argument(text);
    return value;
  } catch (const std::exception&) {
    fail("expected an integer, got '" + text + "'");
  }
}

bool YamlNode::as_bool() const {
  if (!node_.IsScalar()) fail("expected true or false");
  const std::string text = node_.Scalar();
  if (text == "true" || text == "True" || text == "yes") return true;
  if (text == "false" || text == "False" || text == "no") return false;
  fail("expected true or false, got '" + text + "'");
}

std::string YamlNode::as_string() const {
  if (!node_.IsScalar()) fail("expected a text value");
  return node_.Scalar();
}

std::vector<double> YamlNode::as_doubles(std::size_t n) const {
  const auto items = elements();
  if (n != 0 && items.size() != n) {
    fail("expected a list of " + std::to_string(n) + " numbers, got " +
         std::to_string(items.size()));
  }
  std::vector<double> out;
  out.reserve(items.size());
  for (const auto& item : items) out.push_back(item.as_double());
  return out;
}

MapReader::MapReader(const YamlNode& node) : node_(node) {
  if (!node_.node_.IsMap()) node_.fail("expected a mapping of keys to values");
}

bool MapReader::has(std::string_view key) const {
  for (const auto& kv : node_.node_) {
    if (kv.first.Scalar() == key) return true;
  }
  return false;
}

YamlNode MapReader::child(const YAML::Node& key, const YAML::Node& value) const {
  const std::string path =
      node_.path_.empty() ? key.Scalar() : node_.path_ + "." + key.Scalar();
  // A key with no value ("key:") points its mark at the key so errors still name a line.
  if (value.IsNull() && value.Mark().is_null()) return YamlNode(key, node_.file_, path);
  return YamlNode(value, node_.file_, path);
}

std::optional<YamlNode> MapReader::optional(std::string_view key) {
  asked_.emplace(key);
  for (const auto& kv : node_.node_) {
    if (kv.first.Scalar() == key) {
      YamlNode c = child(kv.first, kv.second);
      if (kv.second.IsNull()) c.fail("has no value");
      return c;
    }
  }
  return std::nullopt;
}

YamlNode MapReader::required(std::string_view key) {
  auto n = optional(key);
  if (!n) node_.fail("missing required key '" + std::string(key) + "'");
  return *n;
}

double MapReader::number(std::string_view key, std::optional<double> fallback, double lo,
                         double hi) {
  auto n = optional(key);
  if (!n) {
    if (!fallback) node_.fail("missing required key '" + std::string(key) + "'");
    return *fallback;
  }
  const double v = n->as_double();
  if (v < lo || v > hi) {
    std::ostringstream msg;
    msg << "must be in [" << lo << ", " << hi << "], got " << v;
    n->fail(msg.str());
  }
  return v;
}

double MapReader::positive(std::string_view key, std::optional<double> fallback) {
  auto n = optional(key);
  if (!n) {
    if (!fallback) node_.fail("missing required key '" + std::string(key) + "'");
    return *fallback;
  }
  const double v = n->as_double();
  if (!(v > 0.0)) {
    std::ostringstream msg;
    msg << "must be positive, got " << v;
    n->fail(msg.str());
  }
  return v;
}

std::string MapReader::choice(std::string_view key, std::optional<std::string> fallback,
                              const std::vector<std::string>& allowed) {
  auto n = optional(key);
  if (!n) {
    if (!fallback) node_.fail("missing required key '" + std::string(key) + "'");
    return *fallback;
  }
  const std::string v = n->as_string();
  for (const auto& a : allowed) {
    if (a == v) return v;
  }
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
  n->fail("must be one of [" + list + "], got '" + v + "'");
}

void MapReader::finish() const {
  for (const auto& kv : node_.node_) {
    const std::string key = kv.first.Scalar();
    if (!asked_.contains(key)) {
      const std::string path = node_.path_.empty() ? key : node_.path_ + "." + key;
      YamlNode(kv.first, node_.file_, path)
          .fail("unknown key '" + key + "' (known keys here: " + join(asked_) + ")");
    }
  }
}

}  // namespace syndds
