// What a writer keeps must stay bounded however long a run is. A process that writes and reads
// one topic (every vehicle writes its terrain deformations and reads everyone's) once corrupted
// instance keys when its writing thread and a DDS receive thread computed keys at the same time:
// each corrupted sample became an instance of its own in the writer's KEEP_LAST history and was
// never replaced, so the history grew with the run, and with it the GAPs sent on every
// heartbeat (Fast DDS 2.9 sends one per hole in the history). These tests count, they do not
// time: a late-joining reader is replayed the writer's whole history, which must hold exactly
// `depth` samples of its one key; and every sample a reader receives of one key must carry one
// instance handle.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "core/error.hpp"
#include "dds/convert.hpp"
#include "dds/participant.hpp"
#include "dds_test_util.hpp"

using namespace syndds;
namespace sdds = syndds::dds;
namespace fdds = eprosima::fastdds::dds;

namespace {

constexpr int kDataWriterDepth = 8;  // config/dds/profiles.xml, data_writer (terrain topics)
constexpr int kDomain = 61;

sdds::DdsOptions options(const std::string& run_id) { return dds_test::options(kDomain, run_id); }

msg::TerrainDeformation deformation(const std::string& vehicle, std::int64_t frame) {
  proto::TerrainDeformationMsg d;
  d.vehicle_id = vehicle;
  d.source = "vehicle/" + vehicle;
  d.frame = frame;
  d.spacing_m = 0.05;
  d.vertices.push_back({static_cast<std::int32_t>(frame % 1000), 3, -0.01, 0.0, 0.01, 1e4});
  return sdds::to_dds(d);
}

using dds_test::wait_until;

int matched_readers(sdds::Writer<msg::TerrainDeformation>& w) {
  fdds::PublicationMatchedStatus s;
  w.raw()->get_publication_matched_status(s);
  return s.current_count;
}

// Counts the samples a reader takes, and the distinct instance handles per key.
class CountingListener : public fdds::DataReaderListener {
 public:
  void on_data_available(fdds::DataReader* reader) override {
    msg::TerrainDeformation sample;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&sample, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      std::lock_guard lock(mutex_);
      ++count_[sample.vehicle_id()];
      handles_[sample.vehicle_id()].insert(info.instance_handle);
    }
  }
  int count(const std::string& key) {
    std::lock_guard lock(mutex_);
    return count_[key];
  }
  std::size_t handles(const std::string& key) {
    std::lock_guard lock(mutex_);
    return handles_[key].size();
  }

 private:
  std::mutex mutex_;
  std::map<std::string, int> count_;
  std::map<std::string, std::set<fdds::InstanceHandle_t>> handles_;
};

// Participant "a" writes key "a" and reads the topic, as a vehicle does; participant "b" writes
// key "b" into a's reader at the same time, so a's receive thread computes keys while its
// writing thread does.
struct WriterAndFlood {
  static constexpr int kSamples = 20000;
  const std::string topic = sdds::topics::data(proto::Topic::terrain_deformation);
  sdds::Participant a;
  sdds::Participant b;
  std::unique_ptr<sdds::Writer<msg::TerrainDeformation>> writer_a;
  std::unique_ptr<sdds::Writer<msg::TerrainDeformation>> writer_b;

  explicit WriterAndFlood(const std::string& run)
      : a(options(run)),
        b(options(run)),
        writer_a(a.make_writer<msg::TerrainDeformation>(topic, sdds::profiles::kDataWriter, "a")),
        writer_b(b.make_writer<msg::TerrainDeformation>(topic, sdds::profiles::kDataWriter, "b")) {}

  /// Both write kSamples at once; returns how many of a's writes DDS refused.
  int write_both() {
    std::thread flood([&] {
      for (int k = 0; k < kSamples; ++k) writer_b->write(deformation("b", k));
    });
    int refused = 0;
    for (int k = 0; k < kSamples; ++k) refused += writer_a->write(deformation("a", k)) ? 0 : 1;
    flood.join();
    return refused;
  }
};

}  // namespace

TEST(DdsHistory, WriterThatAlsoReadsItsTopicKeepsOnlyDepthSamplesPerKey) {
  WriterAndFlood w("history-bound");
  auto reader_a = w.a.make_reader<msg::TerrainDeformation>(
      w.topic, sdds::profiles::kDataReader, [](msg::TerrainDeformation&&) {},
      sdds::Participant::Scope::all_vehicles);
  ASSERT_TRUE(wait_until([&] { return matched_readers(*w.writer_b) == 1; }, 10.0));
  ASSERT_TRUE(wait_until([&] { return matched_readers(*w.writer_a) == 1; }, 10.0));
  ASSERT_EQ(w.write_both(), 0);
  ASSERT_TRUE(w.writer_b->wait_for_acknowledgments(10.0));
  ASSERT_TRUE(w.writer_a->wait_for_acknowledgments(10.0));

  // A reader that joins now is replayed a's whole history (TRANSIENT_LOCAL): one key, so at
  // most `depth` samples. Every extra sample is an instance a corrupted key left behind.
  sdds::Participant late(options("history-bound"));
  CountingListener counter;
  {
    // Through the project's own reader, but with a listener that sees the SampleInfo.
    auto probe = late.make_reader<msg::TerrainDeformation>(
        w.topic, sdds::profiles::kDataReader, [](msg::TerrainDeformation&&) {},
        sdds::Participant::Scope::these_vehicles, {"a"});
    ASSERT_EQ(probe->raw()->set_listener(&counter), ReturnCode_t::RETCODE_OK);
    ASSERT_TRUE(wait_until([&] { return matched_readers(*w.writer_a) == 2; }, 10.0));
    ASSERT_TRUE(w.writer_a->wait_for_acknowledgments(10.0));
    ASSERT_TRUE(wait_until([&] { return counter.count("a") >= kDataWriterDepth; }, 10.0));
    // Anything more would have arrived with the acknowledged replay; give stragglers a bound.
    wait_until([&] { return counter.count("a") > kDataWriterDepth; }, 0.5);
    probe->raw()->set_listener(nullptr);
  }
  EXPECT_EQ(counter.count("a"), kDataWriterDepth)
      << "writer a's history holds samples of instances that are not its key";
  EXPECT_EQ(counter.handles("a"), 1u);
}

TEST(DdsHistory, SamplesOfOneKeyCarryOneInstanceHandle) {
  // The receiving side of the same race: a's reader (of key b) computes the keys of what
  // arrives while a's main thread writes.
  WriterAndFlood w("history-handles");
  CountingListener counter;
  auto reader_a = w.a.make_reader<msg::TerrainDeformation>(
      w.topic, sdds::profiles::kDataReader, [](msg::TerrainDeformation&&) {},
      sdds::Participant::Scope::these_vehicles, {"b"});
  ASSERT_EQ(reader_a->raw()->set_listener(&counter), ReturnCode_t::RETCODE_OK);
  ASSERT_TRUE(wait_until([&] { return matched_readers(*w.writer_b) == 1; }, 10.0));
  ASSERT_EQ(w.write_both(), 0);
  ASSERT_TRUE(w.writer_b->wait_for_acknowledgments(10.0));
  reader_a->raw()->set_listener(nullptr);
  EXPECT_GT(counter.count("b"), 0);
  EXPECT_EQ(counter.handles("b"), 1u) << "samples of key b were given several instance handles";
}

// A vehicle that touches many obstacles in one frame writes one collision event per obstacle,
// all of one key and one frame. A reader that matches only after they were written (discovery
// is one-sided at the start of a run) is replayed the writer's history: every one of them must
// still be there, not the last eight.
TEST(DdsHistory, EveryCollisionEventOfOneFrameReachesALateReader) {
  constexpr int kEvents = 40;
  static_assert(kEvents > kDataWriterDepth);
  static_assert(kEvents <= proto::TopicTraits<proto::Topic::collision_event>::max_per_frame);
  const std::string topic = sdds::topics::data(proto::Topic::collision_event);
  sdds::Participant a(options("history-collisions"));
  auto writer = a.make_writer<msg::CollisionEvent>(topic, sdds::profiles::kDataWriter, "a");
  for (int k = 0; k < kEvents; ++k) {
    proto::CollisionEventMsg e;
    e.vehicle_id = "a";
    e.source = "vehicle/a";
    e.frame = 12;
    e.sim_time_s = 0.12;
    e.obstacle_id = "rock" + std::to_string(k);
    e.impulse_ns = 10.0 + k;
    ASSERT_TRUE(writer->write(sdds::to_dds(e)));
  }

  sdds::Participant b(options("history-collisions"));
  std::mutex mutex;
  std::set<std::string> obstacles;
  int received = 0;
  auto reader = b.make_reader<msg::CollisionEvent>(
      topic, sdds::profiles::kDataReader,
      [&](msg::CollisionEvent&& e) {
        const auto m = sdds::from_dds(e);
        std::lock_guard lock(mutex);
        ++received;
        obstacles.insert(m.obstacle_id);
      },
      sdds::Participant::Scope::these_vehicles, {"a"});
  auto count = [&] {
    std::lock_guard lock(mutex);
    return received;
  };
  fdds::PublicationMatchedStatus matched;
  ASSERT_TRUE(wait_until([&] {
    writer->raw()->get_publication_matched_status(matched);
    return matched.current_count == 1;
  }, 10.0));
  ASSERT_TRUE(writer->wait_for_acknowledgments(10.0));
  // Acknowledged means received; the listener may still be taking the last ones.
  wait_until([&] { return count() >= kEvents; }, 10.0);
  std::lock_guard lock(mutex);
  EXPECT_EQ(received, kEvents);
  EXPECT_EQ(obstacles.size(), static_cast<std::size_t>(kEvents));
}

// The history of every data writer holds two frames of the most samples it may write per key
// and frame, on top of its QoS profile; one more sample in a frame is refused, not written over
// a sample a reader may still need.
TEST(DdsHistory, WritersKeepTwoFramesAndRefuseMoreSamplesPerFrame) {
  sdds::Participant p(options("history-limit"));
  auto events = p.make_writer<msg::CollisionEvent>(
      sdds::topics::data(proto::Topic::collision_event), sdds::profiles::kDataWriter, "a");
  const auto qos = events->raw()->get_qos();
  EXPECT_EQ(qos.history().depth,
            2 * static_cast<int>(proto::TopicTraits<proto::Topic::collision_event>::max_per_frame));
  EXPECT_EQ(qos.durability().kind, fdds::TRANSIENT_LOCAL_DURABILITY_QOS);  // the profile's
  EXPECT_EQ(qos.reliability().kind, fdds::RELIABLE_RELIABILITY_QOS);

  constexpr auto kLimit = proto::TopicTraits<proto::Topic::vehicle_state>::max_per_frame;
  auto states = p.make_writer<msg::VehicleState>(
      sdds::topics::data(proto::Topic::vehicle_state), sdds::profiles::kDataWriter, "a");
  EXPECT_EQ(states->raw()->get_qos().history().depth, kDataWriterDepth);
  proto::VehicleStateMsg s;
  s.vehicle_id = "a";
  s.source = "vehicle/a";
  s.frame = 3;
  for (std::uint32_t k = 0; k < kLimit; ++k) EXPECT_TRUE(states->write(sdds::to_dds(s)));
  try {
    states->write(sdds::to_dds(s));
    FAIL() << "a writer accepted more samples of one frame than its history keeps";
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("vehicle_state: sample " + std::to_string(kLimit + 1) +
                                         " of vehicle 'a' in frame 3"),
              std::string::npos)
        << e.what();
  }
  s.frame = 4;
  EXPECT_TRUE(states->write(sdds::to_dds(s)));
}

// A member that leaves right after hearing the coordinator must first be matched with the
// coordinator's readers, or its announcement and failure are lost: a writer knows which
// participants' readers it is matched with (Fast DDS 2.9 leaves get_matched_subscriptions
// unimplemented, so this comes from the matched-status callback).
TEST(DdsMatching, WriterWaitsUntilAGivenParticipantsReaderIsMatched) {
  const std::string topic = sdds::topics::data(proto::Topic::terrain_deformation);
  sdds::Participant writer_side(options("matching"));
  sdds::Participant reader_side(options("matching"));
  sdds::Participant bystander(options("matching"));
  auto writer =
      writer_side.make_writer<msg::TerrainDeformation>(topic, sdds::profiles::kDataWriter, "a");
  sdds::GuidPrefix reader_prefix;
  sdds::GuidPrefix bystander_prefix;
  ASSERT_TRUE(sdds::parse_guid_prefix(reader_side.guid_prefix(), reader_prefix));
  ASSERT_TRUE(sdds::parse_guid_prefix(bystander.guid_prefix(), bystander_prefix));
  // Nobody reads yet: a bounded wait says so.
  EXPECT_FALSE(writer->wait_matched_by(reader_prefix, 0.2));
  auto reader = reader_side.make_reader<msg::TerrainDeformation>(
      topic, sdds::profiles::kDataReader, [](msg::TerrainDeformation&&) {},
      sdds::Participant::Scope::all_vehicles);
  EXPECT_TRUE(writer->wait_matched_by(reader_prefix, 30.0));
  // Another participant (with no reader of this topic) is not taken for the reader's.
  EXPECT_FALSE(writer->wait_matched_by(bystander_prefix, 0.2));
  // The reader goes away: no longer matched, but it was reached; the bystander never was.
  reader.reset();
  EXPECT_TRUE(wait_until([&] { return !writer->wait_matched_by(reader_prefix, 0.0); }, 30.0));
  EXPECT_TRUE(writer->wait_reached_by(reader_prefix, 0.0));
  EXPECT_FALSE(writer->wait_reached_by(bystander_prefix, 0.0));
}

// A reader of some vehicles (a follower needs the vehicle ahead and its convoy's head) is
// matched with those vehicles' writers only: the others' samples, heartbeats and
// acknowledgements never travel to it.
TEST(DdsMatching, AReaderOfSomeVehiclesIsMatchedWithTheirWritersOnly) {
  const std::string topic = sdds::topics::data(proto::Topic::terrain_deformation);
  sdds::Participant writers(options("some-vehicles"));
  sdds::Participant readers(options("some-vehicles"));
  std::map<std::string, std::unique_ptr<sdds::Writer<msg::TerrainDeformation>>> w;
  for (const std::string v : {"a", "b", "c"}) {
    w[v] = writers.make_writer<msg::TerrainDeformation>(topic, sdds::profiles::kDataWriter, v);
  }
  std::mutex mutex;
  std::map<std::string, int> some_received;
  auto some = readers.make_reader<msg::TerrainDeformation>(
      topic, sdds::profiles::kDataReader,
      [&](msg::TerrainDeformation&& d) {
        std::lock_guard lock(mutex);
        ++some_received[std::string(d.vehicle_id())];
      },
      sdds::Participant::Scope::these_vehicles, {"c", "a"});
  // A reader of every vehicle on the same participant: once b's writer is matched with it,
  // the reader side's endpoints are known to the writer side, so b's count is final.
  std::atomic<int> all_received{0};
  auto all = readers.make_reader<msg::TerrainDeformation>(
      topic, sdds::profiles::kDataReader, [&](msg::TerrainDeformation&&) { ++all_received; },
      sdds::Participant::Scope::all_vehicles);
  ASSERT_TRUE(wait_until([&] {
    return matched_readers(*w["a"]) == 2 && matched_readers(*w["b"]) == 1 &&
           matched_readers(*w["c"]) == 2;
  }, 30.0)) << "a " << matched_readers(*w["a"]) << ", b " << matched_readers(*w["b"]) << ", c "
            << matched_readers(*w["c"]);
  for (auto& [v, writer] : w) ASSERT_TRUE(writer->write(deformation(v, 1)));
  for (auto& [v, writer] : w) ASSERT_TRUE(writer->wait_for_acknowledgments(10.0));
  ASSERT_TRUE(wait_until([&] { return all_received == 3; }, 10.0));
  ASSERT_TRUE(wait_until([&] {
    std::lock_guard lock(mutex);
    return some_received["a"] == 1 && some_received["c"] == 1;
  }, 10.0));
  std::lock_guard lock(mutex);
  EXPECT_EQ(some_received.count("b"), 0u);
  EXPECT_EQ(matched_readers(*w["b"]), 1);
}
