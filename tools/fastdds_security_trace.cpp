// Traces Fast DDS 2.9.x's secure discovery in each process of a run: a shared object for
// LD_PRELOAD that wraps the handshake functions of SecurityManager (exported by libfastrtps and
// called through its PLT) and writes one line per call to DIR/<pid>.log. It is how the matching
// race of docs/deployment.md ("DDS Security") was found: in every stuck pair, one side never
// received a single handshake message of the other.
//
//   build/lib/libfastdds_security_trace.so is built with the project (Fast DDS 2.9.0/2.9.1);
//   from the repository:
//   mkdir trace && SYNDDS_SECURITY_TRACE_DIR=$PWD/trace \
//     LD_PRELOAD=$PWD/build/lib/libfastdds_security_trace.so \
//     launch_scripts/run_scenario.sh SCENARIO --security-dir SEC --log-level debug
//   (without SYNDDS_SECURITY_TRACE_DIR: the working directory of each process)
//
// Participants are named by their GUID prefix as the processes' debug lines print them
// ("DDS: discovered participant ..."); a process's own prefix is the one all others discovered.
// The AuthenticationInfo layout below is Fast DDS 2.9.1's (src/cpp/rtps/security/SecurityManager.h).
#include <dlfcn.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fastdds/rtps/builtin/data/ParticipantProxyData.h>
#include <fastdds/rtps/common/CacheChange.h>
#include <mutex>
#include <string>

using eprosima::fastrtps::rtps::CacheChange_t;
using eprosima::fastrtps::rtps::GUID_t;
using eprosima::fastrtps::rtps::ParticipantProxyData;

namespace {

// SecurityManager::DiscoveredParticipantInfo::AuthenticationInfo, 2.9.1.
struct AuthenticationInfo {
  void* identity_handle;
  void* handshake_handle;
  std::uint32_t status;
};

const char* status_of(const void* unique_ptr_to_info) {
  const auto* info = *static_cast<AuthenticationInfo* const*>(unique_ptr_to_info);
  if (info == nullptr) return "taken";  // another thread holds it
  static const char* names[] = {"ok",           "failed",        "init",         "request_not_sent",
                                "waiting_request", "waiting_reply", "waiting_final"};
  return info->status < 7 ? names[info->status] : "?";
}

std::string prefix_of(const GUID_t& guid) {
  char out[40];
  const auto& p = guid.guidPrefix.value;
  std::snprintf(out, sizeof out, "%02x.%02x.%02x.%02x.%02x.%02x.%02x.%02x.%02x.%02x.%02x.%02x",
                p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11]);
  return out;
}

std::mutex g_mutex;

FILE* trace_file() {  // one per process (not per instantiation of trace())
  static FILE* out = [] {
    const char* dir = std::getenv("SYNDDS_SECURITY_TRACE_DIR");
    const std::string path =
        std::string(dir ? dir : ".") + "/" + std::to_string(getpid()) + ".log";
    return std::fopen(path.c_str(), "w");
  }();
  return out;
}

template <typename... A>
void trace(const char* format, A... args) {
  std::lock_guard lock(g_mutex);
  FILE* out = trace_file();
  if (out == nullptr) return;
  timespec t{};
  clock_gettime(CLOCK_REALTIME, &t);
  std::fprintf(out, "%ld.%06ld thread %ld ", static_cast<long>(t.tv_sec),
               static_cast<long>(t.tv_nsec / 1000), static_cast<long>(syscall(SYS_gettid)));
  std::fprintf(out, format, args...);
  std::fputc('\n', out);
  std::fflush(out);
}

template <typename F>
F library(const char* name) {
  void* f = dlsym(RTLD_NEXT, name);
  if (f == nullptr) std::abort();  // only called from the library, which has it
  return reinterpret_cast<F>(f);
}

}  // namespace

#define SM "_ZN8eprosima8fastrtps4rtps8security15SecurityManager"
#define ON_PROCESS_HANDSHAKE                                                               \
  SM "20on_process_handshakeERKNS1_20ParticipantProxyDataERSt10unique_ptrINS3_"           \
     "25DiscoveredParticipantInfo18AuthenticationInfoESt14default_deleteIS9_EEONS2_"     \
     "15MessageIdentityEONS1_10DataHolderE"
#define DISCOVERED_PARTICIPANT SM "22discovered_participantERKNS1_20ParticipantProxyDataE"
#define PARTICIPANT_AUTHORIZED                                                             \
  SM "22participant_authorizedERKNS1_20ParticipantProxyDataERKSt10unique_ptrINS3_"        \
     "25DiscoveredParticipantInfo18AuthenticationInfoESt14default_deleteIS9_EERSt10shared_" \
     "ptrINS2_6HandleEE"
#define STATELESS_MESSAGE SM "37process_participant_stateless_messageEPKNS1_13CacheChange_tE"
#define RESEND "_ZNK8eprosima8fastrtps4rtps8security15SecurityManager30resend_handshake_message_tokenERKNS1_6GUID_tE"

extern "C" bool trace_on_process_handshake(void*, const ParticipantProxyData&, void*, void*, void*)
    __asm__(ON_PROCESS_HANDSHAKE);
extern "C" bool trace_on_process_handshake(void* self, const ParticipantProxyData& remote,
                                           void* info, void* identity, void* message) {
  static const auto f =
      library<bool (*)(void*, const ParticipantProxyData&, void*, void*, void*)>(ON_PROCESS_HANDSHAKE);
  const char* before = status_of(info);
  const bool ok = f(self, remote, info, identity, message);
  trace("handshake step with %s: %s -> %s (%s)", prefix_of(remote.m_guid).c_str(), before,
        status_of(info), ok ? "ok" : "failed");
  return ok;
}

extern "C" bool trace_discovered_participant(void*, const ParticipantProxyData&)
    __asm__(DISCOVERED_PARTICIPANT);
extern "C" bool trace_discovered_participant(void* self, const ParticipantProxyData& remote) {
  static const auto f = library<bool (*)(void*, const ParticipantProxyData&)>(DISCOVERED_PARTICIPANT);
  trace("discovered %s", prefix_of(remote.m_guid).c_str());
  return f(self, remote);
}

extern "C" bool trace_participant_authorized(void*, const ParticipantProxyData&, const void*, void*)
    __asm__(PARTICIPANT_AUTHORIZED);
extern "C" bool trace_participant_authorized(void* self, const ParticipantProxyData& remote,
                                             const void* info, void* secret) {
  static const auto f = library<bool (*)(void*, const ParticipantProxyData&, const void*, void*)>(
      PARTICIPANT_AUTHORIZED);
  const bool ok = f(self, remote, info, secret);
  trace("authorized %s (%s)", prefix_of(remote.m_guid).c_str(), ok ? "ok" : "failed");
  return ok;
}

extern "C" void trace_stateless_message(void*, const CacheChange_t*) __asm__(STATELESS_MESSAGE);
extern "C" void trace_stateless_message(void* self, const CacheChange_t* change) {
  static const auto f = library<void (*)(void*, const CacheChange_t*)>(STATELESS_MESSAGE);
  // Every handshake message reaches every participant; the addressee's is processed.
  trace("handshake message from %s, sequence %u, %u bytes", prefix_of(change->writerGUID).c_str(),
        change->sequenceNumber.low, change->serializedPayload.length);
  f(self, change);
}

extern "C" void trace_resend(const void*, const GUID_t&) __asm__(RESEND);
extern "C" void trace_resend(const void* self, const GUID_t& remote) {
  static const auto f = library<void (*)(const void*, const GUID_t&)>(RESEND);
  trace("resend to %s", prefix_of(remote).c_str());
  f(self, remote);
}
