#pragma once
// Discrete PID with a fixed step, derivative on the error, and integral clamping.
#include <algorithm>

namespace syndds::control {

struct PidGains {
  double kp = 0.0;
  double ki = 0.0;
  double kd = 0.0;
};

class Pid {
 public:
  explicit Pid(PidGains gains, double integral_limit = 10.0)
      : gains_(gains), integral_limit_(integral_limit) {}

  double update(double error, double dt) {
    integral_ = std::clamp(integral_ + error * dt, -integral_limit_, integral_limit_);
    const double derivative = has_previous_ ? (error - previous_) / dt : 0.0;
    previous_ = error;
    has_previous_ = true;
    return gains_.kp * error + gains_.ki * integral_ + gains_.kd * derivative;
  }
  void reset() {
    integral_ = 0.0;
    previous_ = 0.0;
    has_previous_ = false;
  }
  const PidGains& gains() const { return gains_; }
  /// Checkpoint state (the gains come from the configuration).
  template <typename Archive>
  void state_io(Archive& a) {
    a.io(integral_);
    a.io(previous_);
    a.io(has_previous_);
  }

 private:
  PidGains gains_;
  double integral_limit_;
  double integral_ = 0.0;
  double previous_ = 0.0;
  bool has_previous_ = false;
};

}  // namespace syndds::control
