#pragma once
// The single DDS edge of a process: one DomainParticipant with the syndds QoS profiles, the run
// id as partition, typed writers and readers. Everything above this layer speaks the plain
// structs of common/protocol.
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <syndds.h>
#include <synddsPubSubTypes.h>

#include <algorithm>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <mutex>
#include <set>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "dds/convert.hpp"
#include "protocol/messages.hpp"

namespace syndds::dds {

namespace fdds = eprosima::fastdds::dds;

struct DdsOptions {
  int domain_id = 0;
  std::string run_id;            // becomes the DDS partition: runs on one domain never mix
  std::string transport = "default";  // default (shared memory + UDP) | udp | udp_redundant
  std::string discovery_server;  // "ADDR:PORT" of a Fast DDS discovery server; empty: multicast
  std::string profiles_file;     // QoS profiles XML (config/dds/profiles.xml)
  // DDS Security (launch_scripts/make_security.sh): the folder with ca.cert.pem,
  // governance.p7s, permissions.p7s and identities/; empty: no security.
  std::string security_dir;
  std::string identity;  // whose certificate: a member id ("vehicle/a") or "coordinator"
};

/// The participant properties that turn on DDS Security with `options.identity`'s certificate
/// from `options.security_dir`; ConfigError naming a missing file.
std::vector<std::pair<std::string, std::string>> security_properties(const DdsOptions& options);

/// True when this program carries the lock around Fast DDS 2.9.0/2.9.1's secure built-in
/// endpoint matching (services/dds/fastdds_security_race.cpp; not needed from 2.9.2 on).
bool security_race_workaround();
/// With the workaround: checks, in the running process, that the lock is in effect (the loaded
/// libfastrtps is the version it was built for, defines both functions and calls them through
/// its PLT, and the dynamic linker finds this program's locked versions first). Returns why
/// not, or "" (always "" without the workaround). Participants with security refuse to start
/// when it says no.
std::string security_race_check();
/// How many calls of the library went through the locked versions in this process.
std::uint64_t security_race_lock_calls();

/// Topic names, defined once. Protocol topics and one per data topic.
namespace topics {
inline constexpr const char* kMemberAnnounce = "syndds/member_announce";
inline constexpr const char* kFrameGrant = "syndds/frame_grant";
inline constexpr const char* kFrameDone = "syndds/frame_done";
inline constexpr const char* kFrameDones = "syndds/frame_dones";
inline constexpr const char* kRunControl = "syndds/run_control";
std::string data(proto::Topic topic);  // "syndds/vehicle_state", ...
}  // namespace topics

/// QoS profile names in config/dds/profiles.xml.
namespace profiles {
inline constexpr const char* kProtocolWriter = "protocol_writer";
inline constexpr const char* kProtocolReader = "protocol_reader";
inline constexpr const char* kDataWriter = "data_writer";
inline constexpr const char* kDataReader = "data_reader";
inline constexpr const char* kSensorWriter = "sensor_writer";
}  // namespace profiles

/// The PubSubType and registered name of every generated type in the topic tables.
template <typename T>
struct TypeTraits;
#define SYNDDS_DDS_TYPE_(MSG, IDL)                            \
  template <>                                                 \
  struct TypeTraits<msg::IDL> {                               \
    using PubSub = msg::IDL##PubSubType;                      \
    static constexpr const char* name = "syndds::msg::" #IDL; \
  };
#define SYNDDS_DDS_TYPE_TOPIC_(TOPIC, MSG, IDL, LIST, PER_FRAME) SYNDDS_DDS_TYPE_(MSG, IDL)
SYNDDS_PROTOCOL_MESSAGES(SYNDDS_DDS_TYPE_)
SYNDDS_DATA_TOPICS(SYNDDS_DDS_TYPE_TOPIC_)
#undef SYNDDS_DDS_TYPE_TOPIC_
#undef SYNDDS_DDS_TYPE_

/// The generated PubSubType computes instance keys in member buffers (m_keyBuffer, m_md5), but
/// Fast DDS calls getKey from every thread that uses the type: the thread writing a sample and
/// the receive threads of every reader of that topic in the same participant (Fast DDS 2.9
/// writers send no key hash with ALIVE data, so readers compute it from the payload). A vehicle
/// writes and reads terrain_deformation in one process; when two calls overlapped, a sample got
/// a garbage key, became an instance of its own in the writer's KEEP_LAST history and stayed
/// there for good. The history then had ever more holes, and the writer sent a GAP for every
/// one of them with every heartbeat (docs/performance.md, "Soil runs that slowed down").
template <typename PubSub>
class ThreadSafeKeyType : public PubSub {
 public:
  bool getKey(void* data, eprosima::fastrtps::rtps::InstanceHandle_t* handle,
              bool force_md5 = false) override {
    std::lock_guard lock(key_mutex_);
    return PubSub::getKey(data, handle, force_md5);
  }

 private:
  std::mutex key_mutex_;
};

/// How many samples of one key a writer of generated type T may write in one frame: the last
/// column of SYNDDS_DATA_TOPICS for a data topic, 0 (no limit) for the protocol types.
template <typename T>
constexpr std::uint32_t max_per_frame() {
  if constexpr (DdsTopicOf<T>::value.has_value()) {
    return proto::TopicTraits<*DdsTopicOf<T>::value>::max_per_frame;
  } else {
    return 0;
  }
}

/// The history depth per key of a data topic's writers and readers: two frames of samples (at
/// most two frames are in flight, docs/protocol.md), never less than the QoS profile asks for.
/// A KEEP_LAST history one sample too short silently replaces a sample a reader still needs.
template <typename T>
void deepen_history(fdds::HistoryQosPolicy& history) {
  if (history.kind == fdds::KEEP_LAST_HISTORY_QOS && max_per_frame<T>() > 0) {
    history.depth = std::max(history.depth, static_cast<std::int32_t>(2 * max_per_frame<T>()));
  }
}

class Participant;

using GuidPrefix = eprosima::fastrtps::rtps::GuidPrefix_t;

/// Which participants' readers a writer is matched with (Fast DDS 2.9 does not implement
/// DataWriter::get_matched_subscriptions; the matched-status callback names the reader).
class MatchedReaders : public fdds::DataWriterListener {
 public:
  void on_publication_matched(fdds::DataWriter* writer,
                              const fdds::PublicationMatchedStatus& status) override;
  /// Blocks until a reader of participant `prefix` is matched, at most `timeout_s`.
  bool wait_for(const GuidPrefix& prefix, double timeout_s);
  /// Blocks until a reader of participant `prefix` is or was matched, at most `timeout_s`: a
  /// reader matched and gone (its process read what was kept for it and left) was reached.
  bool wait_reached(const GuidPrefix& prefix, double timeout_s);

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::map<GuidPrefix, int> matched_;  // readers per participant
  std::set<GuidPrefix> ever_matched_;  // participants with a reader matched at some time
};

template <typename T>
class Writer {
 public:
  /// `matched` is the listener `writer` was created with.
  Writer(fdds::Publisher* publisher, fdds::DataWriter* writer,
         std::unique_ptr<MatchedReaders> matched)
      : publisher_(publisher), writer_(writer), matched_(std::move(matched)) {}
  ~Writer() { publisher_->delete_datawriter(writer_); }
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;
  /// Returns false if DDS refused the sample (the caller decides how bad that is). Throws
  /// ProtocolError for a sample of a data topic beyond max_per_frame of its key and frame: the
  /// history could not keep it and the samples before it for the readers.
  bool write(const T& sample) {
    if constexpr (max_per_frame<T>() > 0) count_in_frame(sample);
    return writer_->write(const_cast<T*>(&sample));
  }
  fdds::DataWriter* raw() { return writer_; }
  /// Blocks until every matched reader acknowledged everything written (bounded).
  bool wait_for_acknowledgments(double timeout_s);
  /// Blocks until a reader of participant `prefix` is matched (bounded). A writer is matched
  /// with a remote reader some time after the remote participant's own writers were: a sample
  /// written before is never seen by that reader, whatever wait_for_acknowledgments says.
  bool wait_matched_by(const GuidPrefix& prefix, double timeout_s) {
    return matched_->wait_for(prefix, timeout_s);
  }
  /// Blocks until a reader of participant `prefix` is or was matched (bounded): for samples
  /// kept for late readers (transient local), which a reader matched once has received.
  bool wait_reached_by(const GuidPrefix& prefix, double timeout_s) {
    return matched_->wait_reached(prefix, timeout_s);
  }

 private:
  void count_in_frame(const T& sample) {
    auto& [frame, count] = per_key_[sample.vehicle_id()];
    if (count == 0 || frame != sample.frame()) {
      frame = sample.frame();
      count = 0;
    }
    if (++count > max_per_frame<T>()) {
      throw ProtocolError(std::string(proto::TopicTraits<*DdsTopicOf<T>::value>::name) +
                          ": sample " + std::to_string(count) + " of vehicle '" +
                          sample.vehicle_id() + "' in frame " + std::to_string(frame) +
                          "; a writer may write at most " + std::to_string(max_per_frame<T>()) +
                          " per vehicle and frame (SYNDDS_DATA_TOPICS in protocol/messages.hpp)");
    }
  }

  fdds::Publisher* publisher_;
  fdds::DataWriter* writer_;
  std::unique_ptr<MatchedReaders> matched_;  // outlives writer_ (deleted in the destructor)
  std::map<std::string, std::pair<std::int64_t, std::uint32_t>> per_key_;  // frame, count
};

/// The GUID prefix of a sample's writer: the prefix of the participant that wrote it.
inline const GuidPrefix& writer_prefix(const fdds::SampleInfo& info) {
  return info.sample_identity.writer_guid().guidPrefix;
}
/// A prefix as announcements carry it: lowercase hex bytes joined by dots.
std::string to_string(const GuidPrefix& prefix);
/// The inverse; false when `text` is not 12 dot-separated hex bytes.
bool parse_guid_prefix(const std::string& text, GuidPrefix& prefix);

/// Calls `on_sample` from the DDS receive thread for every valid sample taken, with the
/// sample's SampleInfo (who wrote it).
template <typename T>
class Reader : public fdds::DataReaderListener {
 public:
  using Callback = std::function<void(T&&, const fdds::SampleInfo&)>;
  explicit Reader(Callback on_sample) : on_sample_(std::move(on_sample)) {}
  ~Reader() override {
    if (reader_) subscriber_->delete_datareader(reader_);
  }
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  void on_data_available(fdds::DataReader* reader) override {
    fdds::SampleInfo info;
    T sample;
    while (reader->take_next_sample(&sample, &info) == ReturnCode_t::RETCODE_OK) {
      if (info.valid_data) on_sample_(std::move(sample), info);
      sample = T();
    }
  }
  void attach(fdds::Subscriber* subscriber, fdds::DataReader* reader) {
    subscriber_ = subscriber;
    reader_ = reader;
  }
  fdds::DataReader* raw() { return reader_; }

 private:
  Callback on_sample_;
  fdds::Subscriber* subscriber_ = nullptr;
  fdds::DataReader* reader_ = nullptr;
};

class Participant : private fdds::DomainParticipantListener {
 public:
  /// Called from a DDS thread when a remote participant leaves (graceful = it said goodbye)
  /// or is dropped (its liveliness lease expired).
  using LostCallback = std::function<void(const std::string& guid_prefix, bool graceful)>;

  explicit Participant(const DdsOptions& options);
  ~Participant() override;
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  const DdsOptions& options() const { return options_; }
  std::string guid_prefix() const;
  /// Adds a lost-participant callback (several members may share one participant, each with
  /// its own); returns the id that removes it.
  int add_lost_callback(LostCallback cb);
  /// Removes a callback added before. Waits until a call in progress has returned, so its owner
  /// may then be destroyed safely. Unknown ids are ignored.
  void remove_lost_callback(int id);

  /// A writer of a protocol topic (no `vehicle_id`) or of a data topic carrying the samples of
  /// one vehicle key (possibly "", a member of no vehicle): they reach the readers of every key
  /// and the readers of that key only.
  template <typename T>
  std::unique_ptr<Writer<T>> make_writer(const std::string& topic_name, const char* profile,
                                         const std::optional<std::string>& vehicle_id = {}) {
    fdds::Topic* t = topic<T>(topic_name);
    fdds::Publisher* publisher = vehicle_id ? data_publisher(*vehicle_id) : publisher_;
    fdds::DataWriterQos qos;
    if (publisher->get_datawriter_qos_from_profile(profile, qos) != ReturnCode_t::RETCODE_OK) {
      fail(std::string("no data writer QoS profile ") + profile);
    }
    deepen_history<T>(qos.history());
    auto matched = std::make_unique<MatchedReaders>();
    fdds::DataWriter* w = publisher->create_datawriter(t, qos, matched.get(),
                                                       fdds::StatusMask::publication_matched());
    if (!w) fail("cannot create writer for " + topic_name + " with profile " + profile);
    return std::make_unique<Writer<T>>(publisher, w, std::move(matched));
  }

  enum class Scope {
    protocol,      // protocol topics
    all_vehicles,  // data topics, every vehicle's samples
    these_vehicles,  // data topics, the samples of the vehicles in `vehicle_ids` only
  };
  /// Readers of data topics match only the writers they need (partitions per vehicle), so a
  /// controller is not even matched with the other vehicles' state writers: no samples, no
  /// heartbeats, no acknowledgements travel between them.
  /// `on_sample(T&&)` or `on_sample(T&&, const SampleInfo&)` (to know who wrote it).
  template <typename T, typename F>
  std::unique_ptr<Reader<T>> make_reader(const std::string& topic_name, const char* profile,
                                         F&& on_sample, Scope scope = Scope::protocol,
                                         const std::vector<std::string>& vehicle_ids = {}) {
    typename Reader<T>::Callback callback;
    if constexpr (std::is_invocable_v<F&, T&&, const fdds::SampleInfo&>) {
      callback = std::forward<F>(on_sample);
    } else {
      callback = [f = std::forward<F>(on_sample)](T&& sample, const fdds::SampleInfo&) mutable {
        f(std::move(sample));
      };
    }
    return make_reader_impl<T>(topic_name, profile, std::move(callback), scope, vehicle_ids);
  }

 private:
  template <typename T>
  std::unique_ptr<Reader<T>> make_reader_impl(const std::string& topic_name, const char* profile,
                                              typename Reader<T>::Callback on_sample,
                                              Scope scope,
                                              const std::vector<std::string>& vehicle_ids) {
    fdds::Topic* t = topic<T>(topic_name);
    fdds::Subscriber* subscriber = scope == Scope::protocol       ? subscriber_
                                   : scope == Scope::all_vehicles ? data_subscriber({})
                                                                  : data_subscriber(vehicle_ids);
    auto reader = std::make_unique<Reader<T>>(std::move(on_sample));
    fdds::DataReaderQos qos;
    if (subscriber->get_datareader_qos_from_profile(profile, qos) != ReturnCode_t::RETCODE_OK) {
      fail(std::string("no data reader QoS profile ") + profile);
    }
    deepen_history<T>(qos.history());
    fdds::DataReader* r =
        subscriber->create_datareader(t, qos, reader.get(), fdds::StatusMask::data_available());
    if (!r) fail("cannot create reader for " + topic_name + " with profile " + profile);
    reader->attach(subscriber, r);
    return reader;
  }

  void on_participant_discovery(fdds::DomainParticipant* participant,
                                eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override;
  void onParticipantAuthentication(
      fdds::DomainParticipant* participant,
      eprosima::fastrtps::rtps::ParticipantAuthenticationInfo&& info) override;
  [[noreturn]] void fail(const std::string& what) const;
  /// Deletes the DDS participant and everything in it (idempotent).
  void release();
  fdds::Publisher* data_publisher(const std::string& vehicle_id);
  /// Subscribes to the listed vehicles' partitions (none listed: every vehicle).
  fdds::Subscriber* data_subscriber(std::vector<std::string> vehicle_ids);

  template <typename T>
  fdds::Topic* topic(const std::string& name) {
    std::lock_guard lock(mutex_);
    auto it = topics_.find(name);
    if (it != topics_.end()) return it->second;
    fdds::TypeSupport type(new ThreadSafeKeyType<typename TypeTraits<T>::PubSub>());
    if (type.register_type(participant_) != ReturnCode_t::RETCODE_OK &&
        !participant_->find_type(type.get_type_name())) {
      fail(std::string("cannot register type ") + TypeTraits<T>::name);
    }
    fdds::Topic* t = participant_->create_topic(name, type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
    if (!t) fail("cannot create topic " + name);
    topics_[name] = t;
    return t;
  }

  DdsOptions options_;
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;    // protocol topics (partition: run id)
  fdds::Subscriber* subscriber_ = nullptr;
  std::map<std::string, fdds::Publisher*> data_publishers_;    // by vehicle id
  std::map<std::vector<std::string>, fdds::Subscriber*> data_subscribers_;  // by sorted ids
  std::map<std::string, fdds::Topic*> topics_;
  mutable std::mutex mutex_;
  std::mutex callback_mutex_;  // held while a callback runs: removing waits for a call in flight
  std::map<int, LostCallback> lost_;
  int next_callback_id_ = 0;
};

template <typename T>
bool Writer<T>::wait_for_acknowledgments(double timeout_s) {
  const auto secs = static_cast<std::int32_t>(timeout_s);
  const auto nanos = static_cast<std::uint32_t>((timeout_s - secs) * 1e9);
  return writer_->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(secs, nanos)) ==
         ReturnCode_t::RETCODE_OK;
}

/// Process identity for announcements.
std::string host_name();
int process_id();

}  // namespace syndds::dds
