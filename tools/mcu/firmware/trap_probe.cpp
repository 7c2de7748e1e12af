// SPDX-License-Identifier: Apache-2.0
// Proof that the start-up's traps are live (startup.cpp: CCR.UNALIGN_TRP and CCR.DIV_0_TRP,
// ARMv7-M ARM B3.2.8): built once per mode, each does one access the images must never do and
// must end in the named UsageFault, which the CTest tests mcu_m3_trap_* expect. Reaching the
// end of run_image() means the trap did not fire: "no trap" and exit status 0, a failed test.
// TOONFORCE_TRAP_PROBE: 1, a word load from an odd address; 2, an integer division by zero.
#include <cstdint>

#include "board.hpp"

namespace {

// Through volatile: the compiler knows neither the address nor the divisor, so it emits the
// plain LDR and SDIV the hardware must trap.
alignas(4) volatile std::uint8_t g_bytes[8] = {1, 2, 3, 4, 5, 6, 7, 8};
volatile std::uintptr_t g_offset = 1;
volatile std::int32_t g_dividend = 7;
volatile std::int32_t g_divisor = 0;
volatile std::uint32_t g_sink = 0;

}  // namespace

int run_image() {  // called by startup.cpp's reset handler
  namespace board = toonforce::mcu::board;
#if TOONFORCE_TRAP_PROBE == 1
  board::write0("probe: one word load from an odd address\n");
  const std::uintptr_t address = reinterpret_cast<std::uintptr_t>(&g_bytes[0]) + g_offset;
  g_sink = *reinterpret_cast<const volatile std::uint32_t*>(address);
#elif TOONFORCE_TRAP_PROBE == 2
  board::write0("probe: one integer division by zero\n");
  g_sink = static_cast<std::uint32_t>(g_dividend / g_divisor);
#else
#error "TOONFORCE_TRAP_PROBE must be 1 (unaligned load) or 2 (division by zero)"
#endif
  board::write0("no trap\n");
  return 0;
}
