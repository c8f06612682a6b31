// Test helper, not a product: a DDS participant that never announces itself and, for every
// frame grant it sees, writes a DriverCommand for one vehicle that copies the declared
// controller's member id as its `source` (full throttle, full left lock). A vehicle must refuse
// every one of them and record the intrusion; the run's results must not change.
//
//   rogue_commander --domain D --run-id R --vehicle V --source controller/V --profiles XML
#include <CLI/CLI.hpp>

#include <chrono>
#include <csignal>
#include <iostream>
#include <thread>

#include "dds/convert.hpp"
#include "dds/participant.hpp"

namespace sdds = syndds::dds;

int main(int argc, char** argv) {
  CLI::App app{"test helper: writes driver commands with a copied source"};
  sdds::DdsOptions o;
  std::string vehicle, source;
  double seconds = 60.0;
  app.add_option("--domain", o.domain_id)->required();
  app.add_option("--run-id", o.run_id)->required();
  app.add_option("--profiles", o.profiles_file)->required();
  app.add_option("--vehicle", vehicle)->required();
  app.add_option("--source", source)->required();
  app.add_option("--seconds", seconds, "Give up after this long");
  CLI11_PARSE(app, argc, argv);

  sdds::Participant p(o);
  auto writer = p.make_writer<syndds::msg::DriverCommand>(
      sdds::topics::data(syndds::proto::Topic::driver_command), sdds::profiles::kDataWriter,
      vehicle);
  std::atomic<long> written{0};
  std::atomic<bool> ended{false};
  auto grants = p.make_reader<syndds::msg::FrameGrant>(
      sdds::topics::kFrameGrant, sdds::profiles::kProtocolReader,
      [&](syndds::msg::FrameGrant&& g) {
        syndds::proto::DriverCommandMsg c;
        c.vehicle_id = vehicle;
        c.source = source;
        c.frame = g.frame();  // the frame the real controller computes now: the rogue is first
        c.steering = 1.0;
        c.throttle = 1.0;
        if (writer->write(sdds::to_dds(c))) ++written;
      });
  auto control = p.make_reader<syndds::msg::RunControl>(
      sdds::topics::kRunControl, sdds::profiles::kProtocolReader,
      [&](syndds::msg::RunControl&&) { ended = true; });
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!ended && std::chrono::steady_clock::now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  grants.reset();
  control.reset();
  std::cout << "rogue_commander: wrote " << written.load() << " commands\n";
  return 0;
}
