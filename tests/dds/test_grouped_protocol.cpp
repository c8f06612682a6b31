// The time protocol's plumbing for a process that hosts several members, over real Fast DDS:
// one grant reader for all of them (dds::GrantHub) and their dones of a frame in one sample
// (dds::DoneBatch). These count what arrives; they do not time.
#include <gtest/gtest.h>

#include <map>
#include <mutex>

#include "dds/convert.hpp"
#include "dds_test_util.hpp"
#include "dds/done_batch.hpp"
#include "dds/grant_hub.hpp"
#include "dds/participant.hpp"

using namespace syndds;
namespace sdds = syndds::dds;

namespace {

constexpr int kDomain = 62;

sdds::DdsOptions options(const std::string& run_id) { return dds_test::options(kDomain, run_id); }
using dds_test::wait_until;

proto::FrameDoneMsg done_of(const std::string& member, std::int64_t frame) {
  proto::FrameDoneMsg d;
  d.member_id = member;
  d.frame = frame;
  d.published = {{proto::Topic::vehicle_state, "a", member, 1}};
  return d;
}

}  // namespace

// Every member of the process gets every grant, decoded once: the grant, and its whole manifest
// beside it; a malformed grant reaches every member's failure handler; a removed member gets
// nothing more.
TEST(GrantHub, EveryMemberGetsEveryGrantAndEveryMalformedOne) {
  auto group = std::make_shared<sdds::Participant>(options("hub"));
  sdds::GrantHub hub(group);
  std::mutex m;
  std::map<int, std::vector<std::int64_t>> frames;
  std::map<int, std::size_t> manifest_sizes;
  std::map<int, int> failures;
  std::vector<int> ids;
  for (int member = 0; member < 2; ++member) {
    ids.push_back(hub.add(
        [&, member](proto::FrameGrantMsg g, const proto::Manifest& manifest) {
          std::lock_guard lock(m);
          EXPECT_TRUE(g.manifest.empty());  // the manifest comes apart, once for all
          frames[member].push_back(g.frame);
          manifest_sizes[member] = manifest.size();
        },
        [&, member](const std::string& why) {
          std::lock_guard lock(m);
          EXPECT_NE(why.find("unknown topic 'no_such_topic'"), std::string::npos) << why;
          ++failures[member];
        }));
  }
  sdds::Participant coordinator(options("hub"));
  auto writer = coordinator.make_writer<msg::FrameGrant>(sdds::topics::kFrameGrant,
                                                         sdds::profiles::kProtocolWriter);
  proto::FrameGrantMsg grant;
  grant.frame = 3;
  grant.manifest = {{proto::Topic::vehicle_state, "a", "vehicle/a", 1},
                    {proto::Topic::driver_command, "a", "controller/a", 1}};
  ASSERT_TRUE(writer->write(sdds::to_dds(grant)));
  auto got = [&](int member, std::size_t n) {
    std::lock_guard lock(m);
    return frames[member].size() >= n;
  };
  ASSERT_TRUE(wait_until([&] { return got(0, 1) && got(1, 1); }, 30.0));
  {
    std::lock_guard lock(m);
    EXPECT_EQ(frames[0], std::vector<std::int64_t>{3});
    EXPECT_EQ(frames[1], std::vector<std::int64_t>{3});
    EXPECT_EQ(manifest_sizes[0], 2u);
    EXPECT_EQ(manifest_sizes[1], 2u);
  }
  msg::FrameGrant bad = sdds::to_dds(grant);
  bad.frame(4);
  bad.manifest()[0].topic("no_such_topic");
  ASSERT_TRUE(writer->write(bad));
  ASSERT_TRUE(wait_until(
      [&] {
        std::lock_guard lock(m);
        return failures[0] == 1 && failures[1] == 1;
      },
      30.0));
  hub.remove(ids[1]);
  grant.frame = 5;
  ASSERT_TRUE(writer->write(sdds::to_dds(grant)));
  ASSERT_TRUE(wait_until([&] { return got(0, 2); }, 30.0));
  std::lock_guard lock(m);
  EXPECT_EQ(frames[0], (std::vector<std::int64_t>{3, 5}));
  EXPECT_EQ(frames[1], std::vector<std::int64_t>{3});
}

// The dones of a frame travel as one sample once every member taking part answered it.
TEST(DoneBatch, AFramesDonesTravelAsOneSample) {
  auto group = std::make_shared<sdds::Participant>(options("batch"));
  auto batch = std::make_unique<sdds::DoneBatch>(group);
  sdds::Participant coordinator(options("batch"));
  std::mutex m;
  std::vector<std::vector<std::string>> samples;  // "member@frame" per sample
  auto reader = coordinator.make_reader<msg::FrameDones>(
      sdds::topics::kFrameDones, sdds::profiles::kProtocolReader, [&](msg::FrameDones&& s) {
        std::vector<std::string> names;
        for (const auto& d : sdds::from_dds(s).dones) {
          names.push_back(d.member_id + "@" + std::to_string(d.frame));
          EXPECT_EQ(d.published.size(), 1u);
        }
        std::lock_guard lock(m);
        samples.push_back(names);
      });
  batch->add(done_of("vehicle/a", 0));  // frame 0: each takes part from its first done
  batch->add(done_of("controller/a", 0));
  batch->add(done_of("controller/a", 1));
  EXPECT_EQ(batch->samples_written(), 2u);  // held until vehicle/a answers frame 1
  batch->add(done_of("vehicle/a", 1));
  EXPECT_EQ(batch->samples_written(), 3u);
  ASSERT_TRUE(wait_until(
      [&] {
        std::lock_guard lock(m);
        return samples.size() >= 3;
      },
      30.0));
  std::lock_guard lock(m);
  ASSERT_EQ(samples.size(), 3u);
  EXPECT_EQ(samples[2], (std::vector<std::string>{"controller/a@1", "vehicle/a@1"}));
}
