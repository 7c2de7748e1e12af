// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The board under the images: QEMU's mps2-an385 (Cortex-M3) and mps2-an386 (Cortex-M4F).
/// Output and exit go through Arm semihosting (QEMU -semihosting-config enable=on); the
/// instruction counter is the SysTick run from the core clock while QEMU runs in -icount mode.
/// Sources: Arm "Semihosting for AArch32 and AArch64" v3.0 (SYS_WRITE0 0x04, SYS_EXIT 0x18,
/// BKPT 0xAB on M-profile); ARMv7-M ARM B3.3 (SysTick at 0xE000E010); QEMU hw/arm/mps2.c
/// (SYSCLK 25 MHz on AN385/AN386, memory map).

#include <cstdint>

namespace toonforce::mcu::board {

// ---- semihosting ----------------------------------------------------------------------------

inline int semihost(int operation, const void* argument) noexcept {
  register int r0 asm("r0") = operation;
  register const void* r1 asm("r1") = argument;
  asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
  return r0;
}

/// Writes a NUL-terminated string to QEMU's standard output.
inline void write0(const char* text) noexcept { semihost(0x04, text); }

/// Ends the emulation: exit status 0 for 0, 1 for anything else (the 32-bit SYS_EXIT has only
/// the two reasons ApplicationExit and RunTimeErrorUnknown).
[[noreturn]] inline void exit(int code) noexcept {
  semihost(0x18, reinterpret_cast<const void*>(code == 0 ? 0x20026U : 0x20023U));
  for (;;) {
  }
}

// ---- SysTick as an instruction counter --------------------------------------------------------

inline volatile std::uint32_t& reg(std::uintptr_t address) noexcept {
  return *reinterpret_cast<volatile std::uint32_t*>(address);
}
inline constexpr std::uintptr_t kSystCsr = 0xE000E010;
inline constexpr std::uintptr_t kSystRvr = 0xE000E014;
inline constexpr std::uintptr_t kSystCvr = 0xE000E018;

/// The core clock the SysTick counts with CLKSOURCE = 1 (QEMU mps2.c: 25 MHz).
inline constexpr std::uint32_t kCoreClockHz = 25'000'000;

/// Free-running 24-bit down counter at the core clock, no interrupt.
inline void start_systick() noexcept {
  reg(kSystRvr) = 0x00FF'FFFF;
  reg(kSystCvr) = 0;
  reg(kSystCsr) = 0b101;  // CLKSOURCE = core clock, ENABLE, no TICKINT
}

/// The counter now. An inline-asm load with a memory clobber, so the compiler neither moves
/// work across it nor adds instructions between two of them beyond the load itself.
inline std::uint32_t systick_now() noexcept {
  std::uint32_t value;
  asm volatile("ldr %0, [%1]" : "=r"(value) : "r"(kSystCvr) : "memory");
  return value;
}

/// Counts elapsed between two readings (the counter runs down and wraps at 2^24).
inline std::uint32_t systick_elapsed(std::uint32_t earlier, std::uint32_t later) noexcept {
  return (earlier - later) & 0x00FF'FFFFU;
}

inline std::uint32_t stack_pointer() noexcept {
  std::uint32_t sp;
  asm volatile("mov %0, sp" : "=r"(sp));
  return sp;
}

}  // namespace toonforce::mcu::board
