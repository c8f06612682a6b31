// A workaround for a data race in Fast DDS 2.9.0/2.9.1's security plugin layer (Debian 12 ships
// 2.9.1), built only against those versions (services/dds/CMakeLists.txt).
//
// SecurityManager keeps one temporary WriterProxyData/ReaderProxyData per kind of built-in secure
// endpoint and fills it in match_builtin_endpoints() (a newly discovered participant's
// handshake endpoints: ParticipantStatelessMessage) and match_builtin_key_exchange_endpoints()
// (an authenticated participant's key-exchange endpoints: ParticipantVolatileMessageSecure).
// Both run on whichever thread received the triggering message, without a lock: two
// participants discovered at once by two receive threads (multicast, unicast, shared memory)
// fill the same temporary, and one of them is matched under the other's GUID. Its handshake
// messages are then dropped for good (the reader does not know their writer) and the pair never
// authenticates: no error, no retry that helps. Measured on the default scenario (9 secure
// processes): 1 to 2 such pairs in about half the runs; a trace of each process's handshake
// calls showed, in every stuck pair, one side receiving not a single handshake message of the
// other while all other pairs exchanged theirs (docs/deployment.md, "DDS Security").
// Fast DDS 2.9.2 replaced the shared temporaries with pools (eProsima/Fast-DDS pull request
// 3373, "Replaced SecurityManager temporary ProxyDatas with ProxyPools").
//
// The fix here: both functions are exported from libfastrtps and called through its PLT, so
// this program's definitions (exported by the linker options next to this file) take their
// place; each takes a lock and calls the library's own function. The locks guard exactly the
// code the library runs anyway, which takes only the matched endpoints' own mutexes, so they
// add no lock-order cycle.

#include <dlfcn.h>

#include <cstdio>
#include <cstdlib>
#include <mutex>

#include "dds/participant.hpp"

#define SYNDDS_MATCH_BUILTIN                                                           \
  "_ZN8eprosima8fastrtps4rtps8security15SecurityManager23match_builtin_endpointsERKNS1_" \
  "20ParticipantProxyDataE"
#define SYNDDS_MATCH_KEY_EXCHANGE                                             \
  "_ZN8eprosima8fastrtps4rtps8security15SecurityManager36match_builtin_key_" \
  "exchange_endpointsERKNS1_20ParticipantProxyDataE"

namespace {

// void SecurityManager::f(const ParticipantProxyData&): `this` is the first argument.
using MatchFn = void (*)(void* self, const void* participant_data);

MatchFn library_function(const char* name) {
  void* f = dlsym(RTLD_NEXT, name);
  if (f == nullptr) {
    std::fprintf(stderr, "syndds: Fast DDS has no %s (%s)\n", name, dlerror());
    std::abort();  // only reached from inside the library, which calls the function it has
  }
  return reinterpret_cast<MatchFn>(f);
}

std::mutex g_handshake_endpoints;     // SecurityManager::temp_stateless_*_proxy_data_
std::mutex g_key_exchange_endpoints;  // SecurityManager::temp_volatile_*_proxy_data_

void call_locked(const char* name, std::mutex& mutex, void* self, const void* participant_data) {
  const MatchFn library = library_function(name);
  std::lock_guard lock(mutex);
  library(self, participant_data);
}

}  // namespace

extern "C" void syndds_match_builtin_endpoints(void* self, const void* participant_data) __asm__(
    SYNDDS_MATCH_BUILTIN);
extern "C" void syndds_match_builtin_endpoints(void* self, const void* participant_data) {
  call_locked(SYNDDS_MATCH_BUILTIN, g_handshake_endpoints, self, participant_data);
}

extern "C" void syndds_match_key_exchange_endpoints(void* self, const void* participant_data) __asm__(
    SYNDDS_MATCH_KEY_EXCHANGE);
extern "C" void syndds_match_key_exchange_endpoints(void* self, const void* participant_data) {
  call_locked(SYNDDS_MATCH_KEY_EXCHANGE, g_key_exchange_endpoints, self, participant_data);
}

namespace syndds::dds {

bool security_race_workaround() { return true; }

}  // namespace syndds::dds
