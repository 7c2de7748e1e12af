// SPDX-License-Identifier: Apache-2.0
#pragma once
// Shared fixture of the Omni device tests: a fake libHD in manual-stepping mode (each tick runs
// when the test asks), the device opened through the ordinary dlopen path, and a probe tick
// that records what the device said. What passes proves our binding against the documented
// HD API behaviour, not against the real driver.
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "alloc_counter.hpp"
#include "fake_hd_client.hpp"
#include "toonforce/hal/omni/hd_api.hpp"
#include "toonforce/hal/omni/omni_device.hpp"

namespace toonforce::test {

/// One tick as the probe saw it.
struct ProbeRecord {
  ClockedTick clock;
  DeviceStatus status = DeviceStatus::kOk;
  DeviceReading reading;
  DeviceStatus write_status = DeviceStatus::kOk;
  std::size_t allocations = 0;  // this thread's allocation count when the tick ran
};

/// A tick that reads, records, and writes a fixed force (scene frame); kStop at `stop_at_tick`.
struct Probe {
  OmniDevice* device = nullptr;
  Vec3<double> force{};
  std::int64_t stop_at_tick = -1;
  std::vector<ProbeRecord> records;

  Probe() { records.reserve(20000); }  // sized up front: the tick never allocates

  static TickVerdict tick(void* context, const ClockedTick& clock) noexcept {
    auto& self = *static_cast<Probe*>(context);
    ProbeRecord r;
    r.clock = clock;
    r.allocations = allocation_count();
    r.status = self.device->read(r.reading);
    r.write_status = self.device->write(self.force);
    if (self.records.size() < self.records.capacity()) self.records.push_back(r);
    return clock.tick == self.stop_at_tick ? TickVerdict::kStop : TickVerdict::kContinue;
  }
};

class OmniFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    RecordProperty("proves", kProves);
    fake.reset();
    fake.set_manual(1);
    options.library_path = kFakeHd;
    // The cap defaults to the continuous force (0.88 N on the fake); the tests command forces
    // up to the fake's 3.3 N peak, so they raise it as `--omni-max-force` lets a user do.
    // Tests of the default set it back to 0.
    options.max_force_n = 3.3;
  }

  void TearDown() override {
    if (omni) {
      if (omni->running()) {
        omni->request_stop();
        fake.step(1);  // the closing frame runs, so stop() does not have to time out
      }
      omni.reset();
    }
    const TfFakeHdStats s = fake.stats();
    EXPECT_EQ(s.protocol_violations, 0U) << "the binding broke a documented rule: " << s.last_violation_call << " (0x"
                                         << std::hex << s.last_violation << ")";
    fake.reset();
  }

  /// Opens with `options`; fails the test when it does not open.
  OmniDevice& open() {
    auto result = open_omni(options);
    EXPECT_TRUE(result.ok()) << result.error();
    if (!result.ok()) throw std::runtime_error(result.error());
    omni = std::move(result).value();
    return *omni;
  }

  /// Opens and starts with the probe as the tick.
  OmniDevice& start_probe() {
    OmniDevice& device = open();
    probe.device = &device;
    auto started = device.start(&Probe::tick, &probe);
    EXPECT_TRUE(started.ok()) << started.error();
    return device;
  }

  /// The device position [mm] of a scene position [m], from the formula of effects.md §0 with
  /// the fake's workspace centre (0, -5, -5) mm: device = (x, z, -y) * 1000 + centre.
  static void scene_to_device_mm(const Vec3<double>& scene_m, double out_mm[3]) {
    out_mm[0] = scene_m.x * 1000.0;
    out_mm[1] = scene_m.z * 1000.0 - 5.0;
    out_mm[2] = -scene_m.y * 1000.0 - 5.0;
  }
  void pin_scene(const Vec3<double>& scene_m) {
    double d[3];
    scene_to_device_mm(scene_m, d);
    fake.pin_hand(d[0], d[1], d[2]);
  }

  FakeHd fake;
  OmniOptions options;
  std::unique_ptr<OmniDevice> omni;
  Probe probe;
};

}  // namespace toonforce::test
