// SPDX-License-Identifier: Apache-2.0
// toonforce-dds: a running `toonforce run --view`'s devices on DDS, with ROS 2's names and
// types (docs/DDS.md; state_bridge.hpp).
#include <string>

#include <CLI/CLI.hpp>

#include "toonforce/dds/state_bridge.hpp"

int main(int argc, char** argv) {
  toonforce::dds::BridgeOptions o;
  CLI::App app{"Publish a running `toonforce run --view`'s devices on DDS with ROS 2's topic names and types "
               "(rt/toonforce/NAME/pose, twist, wrench, faults; docs/DDS.md)"};
  app.add_option("--view", o.view_url, "The run's viewer, as `run --view` printed it (http://127.0.0.1:PORT/)")
      ->required();
  app.add_option("--domain", o.publisher.domain, "The DDS domain (ROS_DOMAIN_ID), 0 to 232")
      ->capture_default_str()
      ->check(CLI::Range(0, 232));
  app.add_option("--rate", o.publisher.rate_hz, "Samples a second per topic, at most (the newest row each time)")
      ->capture_default_str()
      ->check(CLI::Range(0.001, 10000.0));
  app.add_option("--device-name", o.device_name, "A one-device run's name in topic names (a world's are its own)")
      ->capture_default_str();
  app.add_option("--duration", o.max_seconds, "Stop after this many seconds (0: when the viewer closes or Ctrl-C)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--control-token", o.control_token,
                 "The run's control token (its --control-token): relay scene changes from rt/toonforce/control to "
                 "its control protocol, replies on rt/toonforce/control_reply. Anyone who can write to the DDS "
                 "domain can then change the scene (docs/DDS.md)");
  CLI11_PARSE(app, argc, argv);
  return toonforce::dds::run_bridge(o);
}
