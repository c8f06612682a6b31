#include <gtest/gtest.h>

#include "core/yaml.hpp"

using namespace syndds;

namespace {
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Yaml, ReadsTypedValuesAndRejectsUnknownKeys) {
  auto root = YamlNode::load_string("a: 1.5\nb: true\nc: text\nd: 3\n", "t.yaml");
  MapReader m(root);
  EXPECT_DOUBLE_EQ(m.get<double>("a"), 1.5);
  EXPECT_TRUE(m.get<bool>("b"));
  EXPECT_EQ(m.get<std::string>("c"), "text");
  const std::string err = error_of([&] { m.finish(); });
  EXPECT_NE(err.find("t.yaml:4:1"), std::string::npos) << err;
  EXPECT_NE(err.find("unknown key 'd'"), std::string::npos) << err;
}

TEST(Yaml, ErrorsNameFileLineAndPath) {
  auto root = YamlNode::load_string("time:\n  step_s: abc\n", "s.yaml");
  MapReader m(root);
  MapReader t(m.required("time"));
  const std::string err = error_of([&] { t.get<double>("step_s"); });
  EXPECT_NE(err.find("s.yaml:2:11: time.step_s: expected a number, got 'abc'"), std::string::npos)
      << err;
}

TEST(Yaml, RejectsNonFiniteNumbersAndBounds) {
  auto root = YamlNode::load_string("x: .nan\ny: -2\n", "n.yaml");
  MapReader m(root);
  EXPECT_NE(error_of([&] { m.get<double>("x"); }).find("finite"), std::string::npos);
  EXPECT_NE(error_of([&] { m.positive("y", std::nullopt); }).find("n.yaml:2:4: y: must be positive"),
            std::string::npos);
}

TEST(Yaml, SyntaxErrorNamesLine) {
  const std::string err = error_of([] { YamlNode::load_string("a: [1, 2\nb: 3\n", "bad.yaml"); });
  EXPECT_NE(err.find("bad.yaml:"), std::string::npos) << err;
  EXPECT_NE(err.find("YAML syntax error"), std::string::npos) << err;
}

TEST(Yaml, MissingKeyNamesParent) {
  auto root = YamlNode::load_string("outer:\n  inner: 1\n", "m.yaml");
  MapReader m(root);
  MapReader o(m.required("outer"));
  const std::string err = error_of([&] { o.required("needed"); });
  EXPECT_NE(err.find("m.yaml:2:3: outer: missing required key 'needed'"), std::string::npos) << err;
}
