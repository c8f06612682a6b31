#pragma once
// Small agents for protocol tests: their identity is plain data, so a test writes only the
// behaviour it needs (a step, a finish).
#include <string>
#include <utility>
#include <vector>

#include "protocol/agent.hpp"

namespace syndds::test {

/// Member id, kind, subscriptions, publications and vehicle key as data; does nothing in step().
struct TestAgent : proto::Agent {
  std::string id;
  proto::MemberKind member_kind;
  std::vector<proto::Subscription> subs;
  std::vector<proto::Topic> pubs;
  std::string key;

  TestAgent(std::string member, proto::MemberKind k, std::vector<proto::Subscription> s = {},
            std::vector<proto::Topic> p = {}, std::string vehicle = "")
      : id(std::move(member)), member_kind(k), subs(std::move(s)), pubs(std::move(p)),
        key(std::move(vehicle)) {}
  const std::string& member_id() const override { return id; }
  proto::MemberKind kind() const override { return member_kind; }
  std::vector<proto::Subscription> subscriptions() const override { return subs; }
  std::vector<proto::Topic> publications() const override { return pubs; }
  std::string vehicle_key() const override { return key; }
  void step(const proto::FrameContext&, const proto::FrameSamples&,
            proto::FrameSamples&) override {}
};

/// Member vehicle/x: writes one vehicle_state of vehicle "x" per frame.
struct StateWriter : TestAgent {
  StateWriter()
      : TestAgent("vehicle/x", proto::MemberKind::vehicle, {}, {proto::Topic::vehicle_state},
                  "x") {}
  void step(const proto::FrameContext& ctx, const proto::FrameSamples&,
            proto::FrameSamples& out) override {
    proto::VehicleStateMsg s;
    s.vehicle_id = key;
    s.source = id;
    s.frame = ctx.frame;
    out.vehicle_states.push_back(s);
  }
};

}  // namespace syndds::test
