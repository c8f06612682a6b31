#pragma once
// An Agent is one member of the time barrier (a vehicle, a controller, the recorder, a sensor):
// a deterministic function of the samples stamped frame k-1 that it subscribes to. The same
// Agent runs as its own process (services/*, over DDS) or with others in one process
// (LocalRunner): both deliver exactly the same inputs, so both give the same results.
#include <memory>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/state_io.hpp"
#include "protocol/messages.hpp"

namespace syndds::proto {

/// What an agent depends on: samples of `topic`, all keys or just `key`.
struct Subscription {
  Topic topic;
  std::string key;  // empty: every key
  bool matches(Topic t, const std::string& k) const {
    return t == topic && (key.empty() || key == k);
  }
};

/// The keys of `topic` that `subs` ask for, sorted and each once; empty if none asks for the
/// topic or one asks for every key (a reader of the topic then takes every vehicle's samples).
std::vector<std::string> subscribed_keys(const std::vector<Subscription>& subs, Topic topic);

/// Samples stamped one frame, sorted by (key, source) so their order never depends on arrival.
/// One list per data topic, named in SYNDDS_DATA_TOPICS (vehicle_states, driver_commands, ...).
struct FrameSamples {
#define SYNDDS_FRAME_SAMPLES_LIST_(TOPIC, MSG, IDL, LIST, PER_FRAME) std::vector<MSG> LIST;
  SYNDDS_DATA_TOPICS(SYNDDS_FRAME_SAMPLES_LIST_)
#undef SYNDDS_FRAME_SAMPLES_LIST_
  /// Not a topic: vehicles' collision states (docs/vehicle-contact.md). An agent's outputs hold
  /// its own (at most one, a vehicle's state after the frame; it travels in its FrameDone); its
  /// inputs hold those of frame k-1 the barrier passed on (FrameGrant::bodies: the vehicles
  /// within reach of another, select_contact_bodies), sorted by vehicle_id, for every agent.
  std::vector<VehicleBodyMsg> contact_bodies;

  /// The list of one topic, for code that handles every topic alike.
  template <Topic T>
  std::vector<typename TopicTraits<T>::Msg>& list() {
#define SYNDDS_FRAME_SAMPLES_LIST_(TOPIC, MSG, IDL, LIST, PER_FRAME) \
  if constexpr (T == Topic::TOPIC) return LIST; else
    SYNDDS_DATA_TOPICS(SYNDDS_FRAME_SAMPLES_LIST_)
#undef SYNDDS_FRAME_SAMPLES_LIST_
    static_assert(T != T, "a data topic without a list");
  }
  template <Topic T>
  const std::vector<typename TopicTraits<T>::Msg>& list() const {
    return const_cast<FrameSamples*>(this)->list<T>();
  }

  bool empty() const {
    bool all_empty = contact_bodies.empty();
    for_each_topic([&](auto t) { all_empty = all_empty && list<decltype(t)::value>().empty(); });
    return all_empty;
  }
  void clear() { *this = FrameSamples{}; }
  /// Sorts every list by (key, source): the canonical order agents see.
  void sort();
  /// Manifest entries describing these samples as written by `writer`.
  Manifest manifest(const std::string& writer) const;
  /// Keeps only samples that match one of the subscriptions (and every contact body).
  FrameSamples filtered(const std::vector<Subscription>& subscriptions) const;
  void append(const FrameSamples& other);
};

struct FrameContext {
  std::int64_t frame = 0;     // the frame being computed
  double sim_time_s = 0.0;    // t_k = frame * heartbeat_s, the time at the end of this frame
  double heartbeat_s = 0.0;
  std::vector<std::string> joiners;  // members joining from frame + 1 on (need a snapshot)
  std::vector<std::string> departed;  // members lost (on_member_loss: continue) since the last frame
  std::vector<std::string> intrusions;  // "MEMBER PARTICIPANT what" the coordinator refused
                                        // since the last frame (docs/protocol.md, "Admission")
};

/// How a run ended, as told to every agent.
struct RunEnd {
  RunControlMsg control;
};

/// A sample the transport refused before it reached the frame inbox: its writer is not the
/// participant that announced itself as the member named in its `source` (docs/protocol.md,
/// "Who may write what"). Only the DDS runtime produces these; they arrive when they arrive,
/// so what an agent makes of them is not part of a run's deterministic result.
struct RejectedSample {
  Topic topic = Topic::driver_command;
  std::string key;           // vehicle_id of the sample
  std::string source;        // the member it claims to come from
  std::int64_t frame = 0;    // the frame it claims
  std::string writer;        // GUID prefix of the participant that really wrote it
  std::string reason;
};

class Agent {
 public:
  virtual ~Agent() = default;
  virtual const std::string& member_id() const = 0;
  virtual MemberKind kind() const = 0;
  virtual std::vector<Subscription> subscriptions() const = 0;
  /// Topics this agent may write (the DDS runtime creates writers for exactly these).
  virtual std::vector<Topic> publications() const = 0;
  /// The vehicle every sample this agent writes is about (its vehicle_id); empty if it writes
  /// nothing. Lets the DDS layer deliver samples only to the readers of that vehicle.
  virtual std::string vehicle_key() const { return ""; }

  /// Computes frame `ctx.frame`. `inputs` holds exactly the subscribed samples stamped
  /// ctx.frame - 1 (none for frame 0). Samples to publish go to `outputs`; the runtime stamps
  /// nothing itself: each sample must carry frame == ctx.frame and source == member_id().
  virtual void step(const FrameContext& ctx, const FrameSamples& inputs,
                    FrameSamples& outputs) = 0;

  /// The run ended: completed after `end.control.final_frame`, or aborted (member lost, missed
  /// deadline, interrupt; `end.control.reason` says why). `final_inputs` holds the subscribed
  /// samples stamped with the final frame when they could still be gathered (always after a
  /// completed run; after an abort only if every member had finished that frame).
  virtual void finish(const RunEnd& end, const FrameSamples& final_inputs) {}

  /// Samples of subscribed topics the transport refused since the last frame (called in the
  /// thread that runs frames, before a step).
  virtual void note_rejected(const std::vector<RejectedSample>& rejected) {}

  // ---- checkpoints (docs/checkpoints.md) ----
  /// True if this agent can write and read its state; a scenario that asks for checkpoints is
  /// refused when one of its agents cannot.
  virtual bool can_checkpoint() const { return false; }
  /// Writes everything that decides this agent's frames after the last one it stepped (called
  /// between frames). Afterwards the agent continues from exactly the state load_state would
  /// rebuild from these bytes (a model whose own setters round, e.g. ODE's quaternion
  /// normalisation, passes its state through them here), so a run that checkpoints and one
  /// resumed from that checkpoint step the same numbers.
  virtual void save_state(core::StateWriter& w) {
    throw ProtocolError(member_id() + " cannot write checkpoints");
  }
  /// Restores the state written by save_state into an agent built from the same scenario,
  /// before its first step. Throws core::StateError if the bytes do not fit.
  virtual void load_state(core::StateReader& r) {
    throw ProtocolError(member_id() + " cannot read checkpoints");
  }
};

using AgentPtr = std::unique_ptr<Agent>;

}  // namespace syndds::proto
