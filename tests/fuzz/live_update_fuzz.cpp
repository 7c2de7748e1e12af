// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: a live servo loop whose scene mailbox, and a telemetry ring, are written by
// another process that may write any bytes (docs/spec/live-scenes.md, "What the loop checks").
// Whatever the bytes, for the double and the Q16.16 loop: no crash, no sanitizer report, the
// force finite and within max_force, the telemetry frame filled within its arrays; the frame
// ring's producer writes only its own slots.
//
// Input: byte 0 picks the scalar and what is forged (Mode below); bytes 1..24 are the head and
// tail the "other process" writes into the mailbox and the sequence it writes into the slot;
// byte 25 the HIP's depth into the floor [0.1 mm], byte 26 is spare; the rest are the bytes of one SceneUpdate (cut or
// padded with zeros to its size), pushed as the application would (a well-formed slot) or
// written straight over the slot. The seeds in tests/fuzz/corpus/live_update are valid updates
// of the bundled scenes; TOONFORCE_LIVE_UPDATE_SEEDS=DIR writes them again into DIR (their bytes
// are this build's layout of the update). TOONFORCE_LIVE_UPDATE_VERBOSE says, for each input,
// how many updates the loop applied and refused (are the seeds still valid updates?).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"

namespace toonforce {

/// The bytes the other process can write.
struct ForgeAccess {
  template <class M>
  static auto& head(M& m) {
    return m.head_;
  }
  template <class M>
  static auto& tail(M& m) {
    return m.tail_;
  }
  template <class M>
  static auto& slot(M& m, std::size_t n) {
    return m.slots_[n % M::capacity()];
  }
};

}  // namespace toonforce

namespace {

using namespace toonforce;

enum Mode : std::uint8_t {
  kQ16 = 1,         ///< the Q16.16 loop (else double)
  kRawSlot = 2,     ///< the bytes written over the slot with the header's sequence (else pushed)
  kForgeHead = 4,   ///< the header's head written into the mailbox after the push
  kForgeTail = 8,   ///< the header's tail written into the mailbox after the push
  kAgain = 16,      ///< the update's bytes written over the slot again between ticks
  kRingFirst = 32,  ///< the telemetry ring's indices from the update's first bytes
};
constexpr std::size_t kHeader = 27;

void require(bool ok) {
  if (!ok) std::abort();  // libFuzzer reports the input
}

struct HeldDevice {
  const Vec3<double>* position_m;
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = *position_m;
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>&) noexcept { return DeviceStatus::kOk; }
};

SceneDescription load(const char* name, ScalarKind kind) {
  const std::string path = std::string(TOONFORCE_SOURCE_DIR) + "/scenes/" + name + ".toml";
  return load_scene_file(path, kind).value();
}

/// The scenes: the loop's (the cartoon wall) and those of the seeds' updates.
struct Scenes {
  SceneDescription loop_d, loop_q;
  std::vector<SceneDescription> d, q;
};
const Scenes& scenes() {
  static const Scenes all = [] {
    Scenes s;
    s.loop_d = load("cartoon_wall", ScalarKind::kDouble);
    s.loop_q = load("cartoon_wall", ScalarKind::kQ16_16);
    for (const char* name : {"cartoon_wall", "slippery", "realistic_friction", "cliff", "wall"}) {
      s.d.push_back(load(name, ScalarKind::kDouble));
      s.q.push_back(load(name, ScalarKind::kQ16_16));
    }
    return s;
  }();
  return all;
}

std::uint64_t word(const std::uint8_t* p) {
  std::uint64_t v = 0;
  std::memcpy(&v, p, sizeof v);
  return v;
}

/// The frame ring's producer against a consumer that writes any bytes over the ring: the slot
/// written is always one of the ring's (ASan watches the heap block), and push() never fails
/// but by dropping.
void ring(const std::uint8_t* bytes, std::size_t n) {
  using Ring = SpscRing<std::uint64_t, 8>;
  auto r = std::make_unique<Ring>();
  Ring::Producer producer;
  for (int round = 0; round < 4; ++round) {
    std::memcpy(static_cast<void*>(r.get()), bytes, std::min(n, sizeof(Ring)));  // the other process's bytes
    for (std::uint64_t i = 0; i < 12; ++i) {
      static_cast<void>(r->push(i, producer));
      static_cast<void>(r->push(i));  // the indices in the ring: still within it
    }
    require(producer.head - producer.tail_cache <= Ring::kCapacity || producer.dropped > 0);
  }
}

template <Scalar S>
void run(std::uint8_t mode, const std::uint8_t* header, const std::uint8_t* bytes, std::size_t n) {
  using SceneT = RuntimeScene<S>;
  using Mailbox = SceneMailbox<SceneT>;
  using Update = SceneUpdate<SceneT>;
  const SceneDescription& d = kIsFixed<S> ? scenes().loop_q : scenes().loop_d;
  ServoConfig config = servo_config(d, 1e-3);
  config.safety.soft_start_s = 0.0;
  config.safety.engage_force_n = 1e3;
  const double max_force = d.limits.max_force_n;
  const double slack = kIsFixed<S> ? 1e-3 : 1e-9;

  auto mailbox = std::make_unique<Mailbox>();
  auto update = std::make_unique<Update>();
  std::memcpy(static_cast<void*>(update.get()), bytes, std::min(n, sizeof(Update)));
  const auto write_slot = [&](std::size_t index) {
    auto& slot = ForgeAccess::slot(*mailbox, index);
    std::memcpy(static_cast<void*>(&slot.update), bytes, std::min(n, sizeof(Update)));
    slot.sequence.store(word(header + 16));
  };
  Vec3<double> position{0.0, 0.0, -0.0001 * header[24]};
  using Loop = ServoLoop<HeldDevice, SceneT, NullPins, kLiveStages>;
  auto loop = std::make_unique<Loop>(HeldDevice{&position}, make_runtime_scene<S>(d), config);
  loop->listen(*mailbox);
  TelemetryFrame frame;
  const auto tick = [&](std::int64_t k) {
    static_cast<void>(loop->tick(k));
    const Vec3<double> f = to_double(loop->force());
    require(std::isfinite(f.x) && std::isfinite(f.y) && std::isfinite(f.z));
    require(std::sqrt(dot(f, f)) <= max_force + slack);
    loop->fill_frame(frame);
    require(frame.value_count <= kMaxEffectValues);
  };
  tick(0);
  tick(1);
  if (mode & kRawSlot) {
    write_slot(0);
    ForgeAccess::head(*mailbox).store(1);
  } else {
    static_cast<void>(mailbox->push(*update));
  }
  if (mode & kForgeHead) ForgeAccess::head(*mailbox).store(word(header));
  if (mode & kForgeTail) ForgeAccess::tail(*mailbox).store(word(header + 8));
  const std::uint64_t before = loop->updates_applied() + loop->updates_refused();
  for (std::int64_t k = 2; k < 10; ++k) {
    if ((mode & kAgain) && k % 3 == 0) write_slot(static_cast<std::size_t>(k));
    tick(k);
    // At most one update a tick, whatever the head says.
    require(loop->updates_applied() + loop->updates_refused() <= before + static_cast<std::uint64_t>(k - 1));
  }
  static const bool verbose = std::getenv("TOONFORCE_LIVE_UPDATE_VERBOSE") != nullptr;
  if (verbose) {
    std::fprintf(stderr, "%s loop: %llu update(s) applied, %llu refused\n", kIsFixed<S> ? "q16.16" : "double",
                 static_cast<unsigned long long>(loop->updates_applied()),
                 static_cast<unsigned long long>(loop->updates_refused()));
  }
}

void write_seed(const std::string& dir, const std::string& name, std::uint8_t mode, const void* update,
                std::size_t size) {
  std::vector<std::uint8_t> bytes(kHeader + size, 0);
  bytes[0] = mode;
  const std::uint64_t head = 3, tail = 1, sequence = 2;
  std::memcpy(bytes.data() + 1, &head, 8);
  std::memcpy(bytes.data() + 9, &tail, 8);
  std::memcpy(bytes.data() + 17, &sequence, 8);
  bytes[25] = 20;  // 2 mm into the floor
  std::memcpy(bytes.data() + kHeader, update, size);
  const std::string path = dir + "/" + name;
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) std::abort();
  std::fwrite(bytes.data(), 1, bytes.size(), f);
  std::fclose(f);
}

template <Scalar S>
void write_seeds(const std::string& dir, const std::vector<SceneDescription>& ds, std::uint8_t q) {
  const char* names[] = {"cartoon_wall", "slippery", "realistic_friction", "cliff", "wall"};
  for (std::size_t i = 0; i < ds.size(); ++i) {
    auto u = std::make_unique<SceneUpdate<RuntimeScene<S>>>();
    u->scene = make_runtime_scene<S>(ds[i]);
    u->continues.fill(-1);
    u->sequence = i + 1;
    if (i == 0) {  // the cartoon wall continues the loop's and shakes
      u->continues[0] = 0;
      u->event_count = 1;
      u->events[0] = SceneEvent{0, 0, 0.2};
    }
    const std::string scalar = q != 0 ? "q16" : "double";
    write_seed(dir, std::string(names[i]) + "_" + scalar, q, u.get(), sizeof *u);
    if (i == 0)
      write_seed(dir, std::string(names[i]) + "_raw_" + scalar, static_cast<std::uint8_t>(q | kRawSlot | kAgain),
                 u.get(), sizeof *u);
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  if (const char* dir = std::getenv("TOONFORCE_LIVE_UPDATE_SEEDS")) {
    write_seeds<double>(dir, scenes().d, 0);
    write_seeds<Q16_16>(dir, scenes().q, kQ16);
    std::exit(0);
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < kHeader) return 0;
  const std::uint8_t mode = data[0];
  const std::uint8_t* header = data + 1;
  const std::uint8_t* bytes = data + kHeader;
  const std::size_t n = size - kHeader;
  if (mode & kQ16) {
    run<Q16_16>(mode, header, bytes, n);
  } else {
    run<double>(mode, header, bytes, n);
  }
  if (mode & kRingFirst) {
    ring(bytes, n);
  } else {
    ring(data, size);
  }
  return 0;
}
