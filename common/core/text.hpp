#pragma once
// Numbers in generated text (scenario files): fixed decimals with trailing zeros dropped, and
// never "-0", so that the same value always gives the same bytes.
#include <cstdio>
#include <string>

namespace syndds {

/// `v` with `decimals` decimals (at most 9), trailing zeros and a trailing point removed:
/// 1.500 -> "1.5", 2.000 -> "2", -0.0001 (3 decimals) -> "0".
inline std::string trimmed_decimal(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  std::string s = buf;
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  return s == "-0" ? "0" : s;
}

}  // namespace syndds
