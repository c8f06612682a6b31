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
#include <elf.h>
#include <link.h>

#include <atomic>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>

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
std::atomic<std::uint64_t> g_calls{0};

void call_locked(const char* name, std::mutex& mutex, void* self, const void* participant_data) {
  const MatchFn library = library_function(name);
  std::lock_guard lock(mutex);
  g_calls.fetch_add(1, std::memory_order_relaxed);
  library(self, participant_data);
}

// Whether the loaded object `file` (as the dynamic linker lists it) has a dynamic relocation
// (PLT slot or GOT entry) against `symbol`: its own calls of that function then go through
// the dynamic linker and reach the program's definition. A library linked with -Bsymbolic, or
// whose build inlined or hid the function, has none, and the interposition does nothing.
struct RelocationSearch {
  const char* file;
  const char* symbol;
  bool object_found = false;
  bool relocation_found = false;
};

int search_relocations(dl_phdr_info* info, std::size_t, void* data) {
  auto* search = static_cast<RelocationSearch*>(data);
  if (info->dlpi_name == nullptr || std::strcmp(info->dlpi_name, search->file) != 0) return 0;
  search->object_found = true;
  const ElfW(Dyn)* dynamic = nullptr;
  for (int i = 0; i < info->dlpi_phnum; ++i) {
    if (info->dlpi_phdr[i].p_type == PT_DYNAMIC) {
      dynamic = reinterpret_cast<const ElfW(Dyn)*>(info->dlpi_addr + info->dlpi_phdr[i].p_vaddr);
    }
  }
  if (dynamic == nullptr) return 1;
  // glibc has made these addresses absolute in the loaded dynamic section; a value below the
  // load address is still relative to it.
  auto address = [&](ElfW(Addr) value) {
    return value < info->dlpi_addr ? value + info->dlpi_addr : value;
  };
  const ElfW(Sym)* symbols = nullptr;
  const char* strings = nullptr;
  const ElfW(Rela)* tables[2] = {nullptr, nullptr};
  std::size_t sizes[2] = {0, 0};
  for (const ElfW(Dyn)* d = dynamic; d->d_tag != DT_NULL; ++d) {
    switch (d->d_tag) {
      case DT_SYMTAB: symbols = reinterpret_cast<const ElfW(Sym)*>(address(d->d_un.d_ptr)); break;
      case DT_STRTAB: strings = reinterpret_cast<const char*>(address(d->d_un.d_ptr)); break;
      case DT_JMPREL: tables[0] = reinterpret_cast<const ElfW(Rela)*>(address(d->d_un.d_ptr)); break;
      case DT_PLTRELSZ: sizes[0] = d->d_un.d_val; break;
      case DT_RELA: tables[1] = reinterpret_cast<const ElfW(Rela)*>(address(d->d_un.d_ptr)); break;
      case DT_RELASZ: sizes[1] = d->d_un.d_val; break;
      default: break;
    }
  }
  if (symbols == nullptr || strings == nullptr) return 1;
  for (int t = 0; t < 2 && !search->relocation_found; ++t) {
    if (tables[t] == nullptr) continue;
    for (std::size_t k = 0; k < sizes[t] / sizeof(ElfW(Rela)); ++k) {
      const auto index = ELF64_R_SYM(tables[t][k].r_info);
      if (index != 0 && std::strcmp(strings + symbols[index].st_name, search->symbol) == 0) {
        search->relocation_found = true;
        break;
      }
    }
  }
  return 1;
}

// Why the lock is not in effect for `symbol` ("" when it is): `ours` is this program's version.
std::string check_symbol(const char* symbol, void* ours) {
  if (dlsym(RTLD_DEFAULT, symbol) != ours) {
    return std::string("the dynamic linker does not find this program's locked ") + symbol +
           " first (was the program linked without its export list?)";
  }
  void* library = dlsym(RTLD_NEXT, symbol);
  Dl_info where{};
  if (library == nullptr || dladdr(library, &where) == 0 || where.dli_fname == nullptr) {
    return std::string("the loaded Fast DDS library has no ") + symbol;
  }
  char real[PATH_MAX];
  const std::string file = realpath(where.dli_fname, real) ? real : where.dli_fname;
  const std::string expected = ".so." SYNDDS_FASTDDS_VERSION;
  if (file.size() < expected.size() ||
      file.compare(file.size() - expected.size(), expected.size(), expected) != 0) {
    return "the loaded Fast DDS library is " + file + ", this program was built against Fast DDS " +
           SYNDDS_FASTDDS_VERSION + " (whose race the lock covers): rebuild syndds against the "
           "library it runs with";
  }
  RelocationSearch search{where.dli_fname, symbol};
  dl_iterate_phdr(search_relocations, &search);
  if (!search.object_found || !search.relocation_found) {
    return file + " calls " + symbol + " directly, not through its PLT (a library built with "
           "other flags): the lock cannot reach it";
  }
  return "";
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

std::string security_race_check() {
  static const std::string why = [] {
    std::string out = check_symbol(SYNDDS_MATCH_BUILTIN,
                                   reinterpret_cast<void*>(&syndds_match_builtin_endpoints));
    if (out.empty()) {
      out = check_symbol(SYNDDS_MATCH_KEY_EXCHANGE,
                         reinterpret_cast<void*>(&syndds_match_key_exchange_endpoints));
    }
    return out;
  }();
  return why;
}

std::uint64_t security_race_lock_calls() { return g_calls.load(std::memory_order_relaxed); }

}  // namespace syndds::dds
