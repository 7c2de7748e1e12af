// SPDX-License-Identifier: Apache-2.0
// The tick as a product runs it: the SysTick interrupt starts each servo tick, and the tick talks
// to its device through memory-mapped registers, in the loop's own code (the device's read and
// write below are volatile loads and stores). QEMU's AN385 has no such peripheral, so the register
// block is in RAM, and the main loop acts as the device between interrupts: it fills the position
// registers from the motion, asks for a tick, waits for the handler to finish and reads the force
// registers back, which it prints for the host to compare with replay bit for bit, as main.cpp's
// images do (same output lines). The image is of one scene (the first of image::Scenes).
// Output: "run"/"f"/"end" per motion as main.cpp, then
//   product SCENE handler_tick_max INSTRUCTIONS   the most instructions one tick took in the
//                                                 handler (SysTick readings around it)
//   done
#include <cstdint>
#include <new>

#include "board.hpp"
#include "image.hpp"

namespace toonforce::mcu {
namespace {

using image::Motion;
using S = image::S;

/// The device's register block (in RAM: see above). Positions and velocities as raw Q16.16.
struct DeviceRegisters {
  volatile std::int32_t position[3];
  volatile std::int32_t velocity[3];
  volatile std::uint32_t has_velocity;
  volatile std::int32_t force[3];
  // The sample's stamp (the tick's index and time), as replay's loop takes it from each row.
  volatile std::int64_t t_ns;
  volatile std::uint32_t tick;
  // Handshake between the device (main loop) and the tick (handler).
  volatile std::uint32_t request;
  volatile std::uint32_t done;
  volatile std::uint32_t faults;
  volatile std::uint32_t limits;
};
DeviceRegisters g_registers;

/// The device the loop is built on: its read and write are the register transfers.
struct RegisterDevice {
  using Scalar = S;
  DeviceStatus read(BasicDeviceReading<Scalar>& reading) const noexcept {
    reading.position_m = Vec3<S>{S::from_raw(g_registers.position[0]), S::from_raw(g_registers.position[1]),
                                 S::from_raw(g_registers.position[2])};
    reading.has_velocity = g_registers.has_velocity != 0;
    if (reading.has_velocity) {
      reading.velocity_m_per_s = Vec3<S>{S::from_raw(g_registers.velocity[0]), S::from_raw(g_registers.velocity[1]),
                                         S::from_raw(g_registers.velocity[2])};
    }
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<Scalar>& f) noexcept {
    g_registers.force[0] = f.x.raw();
    g_registers.force[1] = f.y.raw();
    g_registers.force[2] = f.z.raw();
    return DeviceStatus::kOk;
  }
};

template <class>
struct First;
template <class Scene, class... Rest>
struct First<SceneList<Scene, Rest...>> {
  using Type = Scene;
};
using SceneDef = First<image::Scenes>::Type;
using SceneT = SceneDef::Type;
/// Replay's loop (its forces are the ones compared), on the register device.
using Loop = ServoLoop<RegisterDevice, SceneT, NullPins, kSpecStages>;
constexpr SceneT kScene = SceneDef::make();
constexpr Loop kLoop{RegisterDevice{}, kScene, SceneDef::config(image::kMotionPeriodS, true)};
alignas(Loop) unsigned char g_loop_storage[sizeof(Loop)];
Loop* g_loop = nullptr;
std::uint32_t g_handler_max_counts = 0;

/// SysTick at 1 kHz of the 25 MHz core clock (QEMU mps2.c), its interrupt on (ARMv7-M B3.3).
constexpr std::uint32_t kReload = board::kCoreClockHz / 1000 - 1;

void print(const char* text) noexcept { board::write0(text); }
void print_number(std::int64_t value) noexcept {
  char text[24];
  char* p = text + sizeof text;
  *--p = '\0';
  std::uint64_t magnitude = value < 0 ? 0 - static_cast<std::uint64_t>(value) : static_cast<std::uint64_t>(value);
  do {
    *--p = static_cast<char>('0' + magnitude % 10);
    magnitude /= 10;
  } while (magnitude != 0);
  if (value < 0) *--p = '-';
  print(p);
}

}  // namespace
}  // namespace toonforce::mcu

using namespace toonforce::mcu;

/// One servo tick per SysTick interrupt, when the device has asked for one.
extern "C" void SysTick_Handler() {
  if (g_registers.request == 0) return;
  g_registers.request = 0;
  const std::uint32_t before = board::systick_now();
  const toonforce::TickStatus status =
      g_loop->tick(toonforce::Instant{static_cast<std::int64_t>(g_registers.tick), g_registers.t_ns});
  const std::uint32_t after = board::systick_now();
  g_registers.faults = status.faults.bits();
  g_registers.limits = static_cast<std::uint32_t>(status.limits);
  g_registers.done = 1;
  const std::uint32_t counts = board::systick_elapsed(before, after);
  if (counts > g_handler_max_counts) g_handler_max_counts = counts;
}

int run_image() {
  board::reg(board::kSystRvr) = kReload;
  board::reg(board::kSystCvr) = 0;
  board::reg(board::kSystCsr) = 0b111;  // CLKSOURCE = core clock, TICKINT, ENABLE
  for (std::size_t m = 0; m < image::kMotionCount; ++m) {
    const Motion& motion = image::kMotions[m];
    g_loop = new (g_loop_storage) Loop(kLoop);
    print("run ");
    print(SceneDef::kName);
    print(" ");
    print(motion.name);
    print(" ");
    print_number(static_cast<std::int64_t>(motion.count));
    print("\n");
    for (std::size_t row = 0; row < motion.count; ++row) {
      // The device: the sample into its registers, then a tick asked for and waited on.
      const auto& p = motion.rows[row].position_m;
      g_registers.position[0] = p.x.raw();
      g_registers.position[1] = p.y.raw();
      g_registers.position[2] = p.z.raw();
      g_registers.has_velocity = motion.velocity_m_per_s != nullptr ? 1U : 0U;
      if (motion.velocity_m_per_s != nullptr) {
        const auto& v = motion.velocity_m_per_s[row];
        g_registers.velocity[0] = v.x.raw();
        g_registers.velocity[1] = v.y.raw();
        g_registers.velocity[2] = v.z.raw();
      }
      g_registers.t_ns = motion.rows[row].t_ns;
      g_registers.tick = static_cast<std::uint32_t>(row);
      g_registers.done = 0;
      g_registers.request = 1;
      while (g_registers.done == 0) {
      }
      print("f ");
      for (int i = 0; i < 3; ++i) {
        print_number(g_registers.force[i]);
        print(" ");
      }
      print_number(g_registers.faults);
      print(" ");
      print_number(g_registers.limits);
      print("\n");
    }
    print("end\n");
  }
  board::reg(board::kSystCsr) = 0;
  // Instructions from counts, as main.cpp: 2^shift ns each, 40 ns a count.
  const std::uint64_t ns = std::uint64_t{g_handler_max_counts} * (1'000'000'000ULL / board::kCoreClockHz);
  print("product ");
  print(SceneDef::kName);
  print(" handler_tick_max ");
  print_number(
      static_cast<std::int64_t>((ns + (1ULL << (TOONFORCE_MCU_ICOUNT_SHIFT - 1))) >> TOONFORCE_MCU_ICOUNT_SHIFT));
  print("\ndone\n");
  return 0;
}
