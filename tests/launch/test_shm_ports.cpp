#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "launch/shm_ports.hpp"

namespace fs = std::filesystem;
using syndds::launch::remove_stale_shm_ports;

namespace {

struct ShmDir {
  fs::path dir = fs::temp_directory_path() / ("syndds-shm-" + std::to_string(::getpid()));
  ShmDir() {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~ShmDir() { fs::remove_all(dir); }
  // A file as Fast DDS leaves it, last written `age_s` ago.
  fs::path make(const std::string& name, double age_s) const {
    const fs::path f = dir / name;
    std::ofstream(f) << std::string(4096, '\0');
    timespec t[2];
    clock_gettime(CLOCK_REALTIME, &t[0]);
    t[0].tv_sec -= static_cast<time_t>(age_s);
    t[1] = t[0];
    utimensat(AT_FDCWD, f.c_str(), t, 0);
    return f;
  }
  bool has(const std::string& name) const { return fs::exists(dir / name); }
};

}  // namespace

// Domain 3 owns ports 8150..8399. A port file nobody maps, written long ago, goes with its
// lock and mutex files; one a live process maps, one just written (a run starting beside this
// one) and another domain's stay.
TEST(ShmPorts, RemovesOnlyTheDomainsPortsNoProcessUses) {
  ShmDir d;
  d.make("fastrtps_port8150", 60);
  d.make("fastrtps_port8150_el", 60);
  d.make("sem.fastrtps_port8150_mutex", 60);
  const fs::path used = d.make("fastrtps_port8152", 60);
  d.make("fastrtps_port8154", 0);
  d.make("fastrtps_port7400", 60);           // domain 0
  d.make("fastrtps_port8400", 60);           // domain 4
  d.make("fastrtps_0123456789abcdef", 60);   // a writer's data segment, not a port
  const int fd = open(used.c_str(), O_RDWR);
  ASSERT_GE(fd, 0);
  void* map = mmap(nullptr, 4096, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  ASSERT_NE(map, MAP_FAILED);
  close(fd);
  {  // the mapping is this process's; the file's time is what the test set
    timespec t[2];
    clock_gettime(CLOCK_REALTIME, &t[0]);
    t[0].tv_sec -= 60;
    t[1] = t[0];
    utimensat(AT_FDCWD, used.c_str(), t, 0);
  }

  EXPECT_EQ(remove_stale_shm_ports(d.dir.string(), 3), std::vector<int>{8150});
  EXPECT_FALSE(d.has("fastrtps_port8150"));
  EXPECT_FALSE(d.has("fastrtps_port8150_el"));
  EXPECT_FALSE(d.has("sem.fastrtps_port8150_mutex"));
  EXPECT_TRUE(d.has("fastrtps_port8152"));
  EXPECT_TRUE(d.has("fastrtps_port8154"));
  EXPECT_TRUE(d.has("fastrtps_port7400"));
  EXPECT_TRUE(d.has("fastrtps_port8400"));
  EXPECT_TRUE(d.has("fastrtps_0123456789abcdef"));

  munmap(map, 4096);  // its process let go of it: now it is stale too
  EXPECT_EQ(remove_stale_shm_ports(d.dir.string(), 3), std::vector<int>{8152});
  EXPECT_EQ(remove_stale_shm_ports(d.dir.string(), 3, 0.0), std::vector<int>{8154});
  EXPECT_TRUE(d.has("fastrtps_port7400"));
}

TEST(ShmPorts, AMissingFolderRemovesNothing) {
  EXPECT_TRUE(remove_stale_shm_ports("/nonexistent-syndds-shm", 0).empty());
}
