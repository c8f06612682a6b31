#include "dds/participant.hpp"

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastrtps/utils/IPLocator.h>
#include <spdlog/spdlog.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "core/error.hpp"

namespace syndds::dds {

std::string topics::data(proto::Topic topic) {
  return "syndds/" + std::string(proto::to_string(topic));
}

std::string host_name() {
  char buf[256] = {0};
  if (gethostname(buf, sizeof buf - 1) != 0) return "unknown";
  return buf;
}

int process_id() { return static_cast<int>(getpid()); }

namespace {

// The factory keeps loaded profiles process-wide; load each file once.
void load_profiles(const std::string& file) {
  static std::mutex mutex;
  static std::string loaded;
  std::lock_guard lock(mutex);
  if (loaded == file) return;
  if (!std::filesystem::exists(file)) {
    throw ConfigError(file + ": DDS QoS profiles file not found (use --dds-profiles)");
  }
  if (fdds::DomainParticipantFactory::get_instance()->load_XML_profiles_file(file) !=
      ReturnCode_t::RETCODE_OK) {
    throw ConfigError(file + ": Fast DDS could not load these QoS profiles");
  }
  loaded = file;
}

}  // namespace

std::vector<std::pair<std::string, std::string>> security_properties(const DdsOptions& o) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::absolute(o.security_dir);
  std::string file = o.identity;
  for (char& c : file) {
    if (c == '/') c = '.';
  }
  const fs::path cert = dir / "identities" / (file + ".cert.pem");
  const fs::path key = dir / "identities" / (file + ".key.pem");
  for (const auto& f : {dir / "ca.cert.pem", dir / "governance.p7s", dir / "permissions.p7s",
                        cert, key}) {
    if (!fs::exists(f)) {
      throw ConfigError("DDS security: " + f.string() + " is missing (launch_scripts/" +
                        "make_security.sh SCENARIO writes the identities of its members)");
    }
  }
  const std::string pki = "dds.sec.auth.builtin.PKI-DH.";
  const std::string acl = "dds.sec.access.builtin.Access-Permissions.";
  return {{"dds.sec.auth.plugin", "builtin.PKI-DH"},
          {pki + "identity_ca", "file://" + (dir / "ca.cert.pem").string()},
          {pki + "identity_certificate", "file://" + cert.string()},
          {pki + "private_key", "file://" + key.string()},
          {"dds.sec.access.plugin", "builtin.Access-Permissions"},
          {acl + "permissions_ca", "file://" + (dir / "ca.cert.pem").string()},
          {acl + "governance", "file://" + (dir / "governance.p7s").string()},
          {acl + "permissions", "file://" + (dir / "permissions.p7s").string()},
          {"dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC"}};
}

namespace {

// A UDP port no socket of this host holds now (the kernel's choice); Fast DDS binds it shortly
// after. Another process taking it in between makes the participant's creation fail (named).
std::uint32_t free_udp_port() {
  const int s = socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_ANY);
  socklen_t length = sizeof a;
  const bool ok = s >= 0 && bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
                  getsockname(s, reinterpret_cast<sockaddr*>(&a), &length) == 0;
  if (s >= 0) close(s);
  if (!ok) throw ConfigError("transport udp_redundant: no free UDP port");
  return ntohs(a.sin_port);
}

// transport udp_redundant: the participant listens on two unicast ports for discovery traffic
// and two for data, on every address of the host. Fast DDS sends each datagram to every
// unicast locator a receiver announces and drops the second copy by its sequence number, so a
// datagram is lost only when both copies are. Explicit unicast lists replace Fast DDS's
// default locators, multicast discovery included: the multicast locator is listed again.
void listen_twice(fdds::DomainParticipantQos& qos) {
  using eprosima::fastrtps::rtps::IPLocator;
  using eprosima::fastrtps::rtps::Locator_t;
  auto& wire = qos.wire_protocol();
  Locator_t multicast;
  multicast.kind = LOCATOR_KIND_UDPv4;
  IPLocator::setIPv4(multicast, 239, 255, 0, 1);
  multicast.port = 0;  // Fast DDS's well-known discovery port of the domain
  wire.builtin.metatrafficMulticastLocatorList.clear();
  wire.builtin.metatrafficMulticastLocatorList.push_back(multicast);
  wire.builtin.metatrafficUnicastLocatorList.clear();
  wire.default_unicast_locator_list.clear();
  for (int copy = 0; copy < 2; ++copy) {
    Locator_t discovery;  // address 0: every interface
    discovery.kind = LOCATOR_KIND_UDPv4;
    discovery.port = free_udp_port();
    wire.builtin.metatrafficUnicastLocatorList.push_back(discovery);
    Locator_t data;
    data.kind = LOCATOR_KIND_UDPv4;
    data.port = free_udp_port();
    wire.default_unicast_locator_list.push_back(data);
  }
  const auto& m = wire.builtin.metatrafficUnicastLocatorList;
  const auto& d = wire.default_unicast_locator_list;
  spdlog::info("DDS: transport udp_redundant: unicast ports {} {} (discovery), {} {} (data)",
               m.begin()->port, (m.begin() + 1)->port, d.begin()->port, (d.begin() + 1)->port);
}

}  // namespace

// Built against a Fast DDS without the race (the other definition: fastdds_security_race.cpp).
#if !SYNDDS_FASTDDS_SECURITY_RACE_WORKAROUND
bool security_race_workaround() { return false; }
std::string security_race_check() { return ""; }
std::uint64_t security_race_lock_calls() { return 0; }
#endif

Participant::Participant(const DdsOptions& options) : options_(options) {
  load_profiles(options_.profiles_file);
  if (!options_.discovery_server.empty()) {
    // Fast DDS 2.9 turns a SIMPLE participant into a discovery-server CLIENT when this is set
    // (FASTDDS_DISCOVERY_SERVER is not read by 2.9.1).
    setenv("ROS_DISCOVERY_SERVER", options_.discovery_server.c_str(), 1);
  }
  const bool redundant = options_.transport == "udp_redundant";
  if (redundant && !options_.discovery_server.empty()) {
    throw ConfigError("transport udp_redundant works with multicast discovery, not with a "
                      "discovery server (" + options_.discovery_server + ")");
  }
  const char* profile =
      options_.transport == "default" ? "syndds_participant" : "syndds_participant_udp";
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  if (options_.security_dir.empty() && !redundant) {
    participant_ = factory->create_participant_with_profile(
        static_cast<fdds::DomainId_t>(options_.domain_id), profile, this,
        fdds::StatusMask::none());
  } else {
    // The profile's QoS plus the security plugins with this member's identity (set in code:
    // each process has its own certificate) and/or the redundant unicast locators.
    fdds::DomainParticipantQos qos;
    if (factory->get_participant_qos_from_profile(profile, qos) != ReturnCode_t::RETCODE_OK) {
      throw ConfigError(std::string("no participant profile ") + profile + " in " +
                        options_.profiles_file);
    }
    if (redundant) listen_twice(qos);
    if (!options_.security_dir.empty()) {
      for (const auto& [name, value] : security_properties(options_)) {
        qos.properties().properties().emplace_back(name, value);
      }
    }
    if (!options_.security_dir.empty() && security_race_workaround()) {
      // Secure discovery without the lock loses participant pairs for good: refuse it.
      if (const std::string why = security_race_check(); !why.empty()) {
        throw ConfigError("DDS Security cannot run safely in this process: " + why);
      }
      spdlog::debug("DDS Security: Fast DDS 2.9.1's built-in endpoint matching runs under a lock");
    }
    participant_ = factory->create_participant(static_cast<fdds::DomainId_t>(options_.domain_id),
                                               qos, this, fdds::StatusMask::none());
  }
  if (!participant_) {
    throw ConfigError("cannot create a DDS participant on domain " +
                      std::to_string(options_.domain_id) + " with profile " + profile);
  }
  fdds::PublisherQos pub_qos = participant_->get_default_publisher_qos();
  pub_qos.partition().push_back(options_.run_id.c_str());
  publisher_ = participant_->create_publisher(pub_qos);
  fdds::SubscriberQos sub_qos = participant_->get_default_subscriber_qos();
  sub_qos.partition().push_back(options_.run_id.c_str());
  subscriber_ = participant_->create_subscriber(sub_qos);
  if (!publisher_ || !subscriber_) {
    // The destructor does not run for a constructor that throws: the participant, whose
    // listener is this object, goes first.
    release();
    fail("cannot create publisher/subscriber");
  }
}

Participant::~Participant() { release(); }

void Participant::release() {
  if (!participant_) return;
  participant_->set_listener(nullptr);
  participant_->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
  participant_ = nullptr;
}

void MatchedReaders::on_publication_matched(fdds::DataWriter*,
                                            const fdds::PublicationMatchedStatus& status) {
  const GuidPrefix prefix =
      eprosima::fastrtps::rtps::iHandle2GUID(status.last_subscription_handle).guidPrefix;
  {
    std::lock_guard lock(mutex_);
    int& n = matched_[prefix];
    n += status.current_count_change;
    if (n <= 0) matched_.erase(prefix);
    if (status.current_count_change > 0) ever_matched_.insert(prefix);
  }
  cv_.notify_all();
}

bool MatchedReaders::wait_for(const GuidPrefix& prefix, double timeout_s) {
  std::unique_lock lock(mutex_);
  return cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                      [&] { return matched_.contains(prefix); });
}

bool MatchedReaders::wait_reached(const GuidPrefix& prefix, double timeout_s) {
  std::unique_lock lock(mutex_);
  return cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                      [&] { return ever_matched_.contains(prefix); });
}

std::string to_string(const GuidPrefix& prefix) {
  std::ostringstream out;
  out << prefix;
  return out.str();
}

bool parse_guid_prefix(const std::string& text, GuidPrefix& prefix) {
  std::istringstream in(text);
  in >> prefix;
  return !in.fail() && to_string(prefix) == text;
}

std::string Participant::guid_prefix() const {
  std::ostringstream out;
  out << participant_->guid().guidPrefix;
  return out.str();
}

int Participant::add_lost_callback(LostCallback cb) {
  std::lock_guard lock(callback_mutex_);
  const int id = next_callback_id_++;
  lost_.emplace(id, std::move(cb));
  return id;
}

void Participant::remove_lost_callback(int id) {
  std::lock_guard lock(callback_mutex_);
  lost_.erase(id);
}

void Participant::on_participant_discovery(
    fdds::DomainParticipant*, eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) {
  using Info = eprosima::fastrtps::rtps::ParticipantDiscoveryInfo;
  // Called for every announcement received (CHANGED_QOS_PARTICIPANT): nothing to do for those.
  const bool discovered = info.status == Info::DISCOVERED_PARTICIPANT;
  const bool gone =
      info.status == Info::REMOVED_PARTICIPANT || info.status == Info::DROPPED_PARTICIPANT;
  if (!gone && !(discovered && spdlog::should_log(spdlog::level::debug))) return;
  std::ostringstream out;
  out << info.info.m_guid.guidPrefix;
  if (discovered) {
    spdlog::debug("DDS: discovered participant {}", out.str());
    return;
  }
  std::lock_guard lock(callback_mutex_);
  for (const auto& [id, lost] : lost_) lost(out.str(), info.status == Info::REMOVED_PARTICIPANT);
}

// With DDS Security a discovered participant (above) is heard only once its handshake
// succeeded; a refused one is worth a warning (a process with a certificate of another CA, or a
// bad one, is trying to join). Both lines name pairs stuck in the handshake (docs/deployment.md).
void Participant::onParticipantAuthentication(
    fdds::DomainParticipant*, eprosima::fastrtps::rtps::ParticipantAuthenticationInfo&& info) {
  using Info = eprosima::fastrtps::rtps::ParticipantAuthenticationInfo;
  std::ostringstream out;
  out << info.guid.guidPrefix;
  if (info.status == Info::AUTHORIZED_PARTICIPANT) {
    spdlog::debug("DDS Security: participant {} authenticated", out.str());
  } else {
    spdlog::warn("DDS Security: participant {} failed authentication", out.str());
  }
}

// Partitions of data topics: writers of vehicle V publish in "<run>/all" and "<run>/vehicle/V";
// a reader of every vehicle subscribes to "<run>/all", a reader of V and W to "<run>/vehicle/V"
// and "<run>/vehicle/W" (it matches a writer whose partitions share one of its own).
fdds::Publisher* Participant::data_publisher(const std::string& vehicle_id) {
  std::lock_guard lock(mutex_);
  auto& p = data_publishers_[vehicle_id];
  if (!p) {
    fdds::PublisherQos qos = participant_->get_default_publisher_qos();
    qos.partition().push_back((options_.run_id + "/all").c_str());
    qos.partition().push_back((options_.run_id + "/vehicle/" + vehicle_id).c_str());
    p = participant_->create_publisher(qos);
    if (!p) fail("cannot create a publisher for vehicle " + vehicle_id);
  }
  return p;
}

fdds::Subscriber* Participant::data_subscriber(std::vector<std::string> vehicle_ids) {
  std::sort(vehicle_ids.begin(), vehicle_ids.end());
  vehicle_ids.erase(std::unique(vehicle_ids.begin(), vehicle_ids.end()), vehicle_ids.end());
  std::lock_guard lock(mutex_);
  auto& s = data_subscribers_[vehicle_ids];
  if (!s) {
    fdds::SubscriberQos qos = participant_->get_default_subscriber_qos();
    if (vehicle_ids.empty()) qos.partition().push_back((options_.run_id + "/all").c_str());
    for (const auto& id : vehicle_ids) {
      qos.partition().push_back((options_.run_id + "/vehicle/" + id).c_str());
    }
    s = participant_->create_subscriber(qos);
    if (!s) {
      std::string names;
      for (const auto& id : vehicle_ids) names += (names.empty() ? "" : ", ") + id;
      fail("cannot create a subscriber for " + (names.empty() ? "every vehicle" : names));
    }
  }
  return s;
}

void Participant::fail(const std::string& what) const {
  throw std::runtime_error("DDS: " + what + " (domain " + std::to_string(options_.domain_id) +
                           ", run " + options_.run_id + ")");
}

}  // namespace syndds::dds
