#pragma once
// What a scenario's `v2v:` block says (v2v.hpp simulates it): plain data for the config layer.

namespace syndds::convoy {

struct V2VConfig {
  double rate_hz = 10.0;
  double latency_s = 0.0;
  double drop_probability = 0.0;  // in [0, 1]; 1 cuts the link
};

}  // namespace syndds::convoy
