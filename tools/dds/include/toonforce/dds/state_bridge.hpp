// SPDX-License-Identifier: Apache-2.0
#pragma once
/// toonforce's devices on DDS, as ROS 2 sees them (docs/DDS.md): `toonforce-dds` reads a
/// running `toonforce run --view`'s telemetry from the viewer's read-only WebSocket and
/// publishes each device's state on a DDS domain, with ROS 2's names and types:
///
///   rt/toonforce/NAME/pose    geometry_msgs/msg/PoseStamped   the HIP [m] (world frame in a world)
///   rt/toonforce/NAME/twist   geometry_msgs/msg/TwistStamped  its velocity [m/s] (one device: the loop's estimate)
///   rt/toonforce/NAME/wrench  geometry_msgs/msg/WrenchStamped the commanded force [N]
///   rt/toonforce/NAME/faults  std_msgs/msg/UInt32             the latched fault bits (control/faults.hpp)
///
/// With a control token (`--control-token`), scene changes come in too, through the control
/// protocol and so through all its checks in the run's server process:
///
///   rt/toonforce/control        std_msgs/msg/String  one control protocol message (JSON), reliable
///   rt/toonforce/control_reply  std_msgs/msg/String  its reply, in order, reliable
///
/// It runs in a process of its own, apart from the loop's: the network's bytes (DDS discovery
/// and data from any host of the domain) are parsed there, never in the process that holds the
/// device, and the loop never waits on it (the viewer's server drops frames for a slow page
/// and counts them). What the bridge gets is what the viewer shows: every device's values per
/// servo tick; it publishes at most `rate_hz` samples a second per topic, the newest.

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"

namespace toonforce::dds {

/// Where one device's values are in the viewer's rows (indices into a row).
struct DeviceColumns {
  std::string name;
  std::size_t x = 0, y = 0, z = 0;
  std::optional<std::size_t> vx, vy, vz;  ///< a world's rows carry no velocity
  std::size_t fx = 0, fy = 0, fz = 0;
  std::size_t latched = 0;
};

/// The devices of a viewer's `columns` (its hello): one device ("x", "fx", "latched", ...:
/// named `one_device_name`), or a world's ("NAME.x", "NAME.fx", "NAME.latched", ...: every NAME
/// with a "NAME.state" column). An error names the column that is missing.
Result<std::vector<DeviceColumns>> device_columns(const std::vector<std::string>& columns,
                                                  std::string_view one_device_name);

/// The DDS topic of a device's `what` ("pose", "twist", "wrench", "faults"): ROS 2's topic
/// /toonforce/NAME/WHAT as its DDS middlewares name it ("rt/" in front).
std::string topic_name(std::string_view device, std::string_view what);

/// Whether `name` may be a ROS 2 name's token (letters, digits, underscores; not starting with
/// a digit): a device name that is not cannot be a topic.
bool ros_token(std::string_view name) noexcept;

/// Whether `text` is UTF-8 without overlongs or surrogates (RFC 3629): what a WebSocket text
/// message must be. The control server closes a connection that sends one that is not, so the
/// relay refuses such a message itself rather than lose the connection for every later one.
bool utf8(std::string_view text) noexcept;

struct PublisherOptions {
  std::uint32_t domain = 0;
  double rate_hz = 100.0;                    ///< per topic, at most
  std::string frame_id = "toonforce_world";  ///< header.frame_id of every message
};

/// One DDS participant with four writers per device (best effort, keep last 1, a deadline of
/// three publishing periods, automatic liveliness with a 1 s lease: a reader sees a run that
/// stopped as a missed deadline, a bridge that died as lost liveliness).
class StatePublisher {
 public:
  static Result<std::unique_ptr<StatePublisher>> open(const std::vector<DeviceColumns>& devices,
                                                      const PublisherOptions& options);
  ~StatePublisher();
  StatePublisher(const StatePublisher&) = delete;
  StatePublisher& operator=(const StatePublisher&) = delete;

  /// One row of the viewer's (servo tick `t_s` of the run): published if it is at least one
  /// publishing period after the last published, stamped with this host's clock. Rows with a
  /// value that is not finite where a message needs one are skipped (counted).
  void offer(std::span<const double> row, double t_s);
  std::uint64_t published() const noexcept { return published_; }
  /// The DDS participant (for the control relay's reader and writer in the same domain).
  std::int32_t participant() const noexcept;
  std::uint64_t skipped() const noexcept { return skipped_; }

 private:
  struct Impl;
  explicit StatePublisher(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  std::uint64_t published_ = 0;
  std::uint64_t skipped_ = 0;
};

struct BridgeOptions {
  std::string view_url;                ///< ws://HOST:PORT/ws of `run --view` (or http://HOST:PORT/)
  std::string device_name = "device";  ///< a one-device run's device in topic names
  PublisherOptions publisher;
  double max_seconds = 0.0;  ///< stop after this long (0: when the viewer closes or a stop signal)
  /// Set (the run's --control-token): also relay the control protocol. Each std_msgs/String on
  /// rt/toonforce/control is one control message (docs/spec/control-protocol.md), sent to the
  /// run's /control as it is; its reply comes back on rt/toonforce/control_reply. Empty: no
  /// control topic at all.
  std::string control_token;
};

/// Connects to the viewer, opens the publisher from its hello and publishes until the viewer
/// closes the connection, a stop signal comes, or max_seconds pass. Prints what it does on
/// standard error. Returns the exit status (0 done, 1 the connection failed midway, 2 could
/// not start: the message says why and what to do).
int run_bridge(const BridgeOptions& options);

}  // namespace toonforce::dds
