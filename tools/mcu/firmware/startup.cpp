// Reset and fault handling for the mps2 boards: the vector table, .data and .bss set up, the
// stack painted (for its high-water mark), divide-by-zero and fault traps, then main().
// No C runtime start files (-nostartfiles) and no heap: nothing here or in the image may
// allocate (mps2.ld fails the link if malloc or operator new is linked at all).
#include <cstdint>

#include "board.hpp"
#include "stack_paint.hpp"

extern "C" {
// From mps2.ld.
extern std::uint32_t __data_start, __data_end, __data_load, __bss_start, __bss_end;
extern std::uint32_t __stack_bottom, __stack_top;
extern void (*__init_array_start[])();
extern void (*__init_array_end[])();

[[noreturn]] void Reset_Handler();
}
int run_image();  // main.cpp (not main: C++ forbids calling main, and nothing else would)

namespace {

[[noreturn]] void trap(const char* what) {
  toonforce::mcu::board::write0("trap: ");
  toonforce::mcu::board::write0(what);
  toonforce::mcu::board::write0("\n");
  toonforce::mcu::board::exit(1);
}

void nmi() { trap("NMI"); }
void hard_fault() { trap("HardFault"); }
void mem_manage() { trap("MemManage fault"); }
void bus_fault() { trap("BusFault"); }
void usage_fault() { trap("UsageFault (undefined instruction, divide by zero or unaligned access)"); }
void unexpected() { trap("unexpected exception"); }

using Handler = void (*)();
struct VectorTable {
  const void* initial_sp;
  Handler handlers[15];
};

}  // namespace

// The SysTick's handler: an image that ticks from the interrupt defines it (product.cpp); any
// other image takes this one, as it takes no SysTick interrupt.
extern "C" [[gnu::weak]] void SysTick_Handler() { trap("unexpected exception"); }

// ARMv7-M ARM B1.5.3: initial SP, then Reset, NMI, HardFault, MemManage, BusFault, UsageFault,
// 4 reserved, SVCall, DebugMonitor, reserved, PendSV, SysTick. No device interrupts are used.
[[gnu::section(".vectors"), gnu::used]] const VectorTable kVectorTable = {
    &__stack_top,
    {Reset_Handler, nmi, hard_fault, mem_manage, bus_fault, usage_fault, nullptr, nullptr, nullptr, nullptr,
     unexpected, unexpected, nullptr, unexpected, SysTick_Handler}};

// A 64-bit division by zero (__aeabi_ldivmod) calls these instead of trapping in hardware;
// Fixed never divides by zero, so reaching one is a bug to stop on.
extern "C" void __aeabi_idiv0() { trap("integer division by zero"); }
extern "C" void __aeabi_ldiv0() { trap("64-bit division by zero"); }
// Without an OS there is nowhere to abort to (std::abort, a failed assert).
extern "C" [[noreturn]] void _exit(int) { trap("_exit called (abort or assert)"); }

extern "C" [[noreturn]] void Reset_Handler() {
  toonforce::mcu::paint_stack_below(toonforce::mcu::board::stack_pointer());
  // .data from its load address in flash; .bss zeroed (element loops: no library calls yet).
  for (std::uint32_t *src = &__data_load, *dst = &__data_start; dst < &__data_end;) *dst++ = *src++;
  for (std::uint32_t* dst = &__bss_start; dst < &__bss_end;) *dst++ = 0;
  for (auto* f = __init_array_start; f < __init_array_end; ++f) (*f)();

  // Trap integer division by zero (SDIV/UDIV), and report MemManage, BusFault and UsageFault
  // as themselves rather than escalated to HardFault (ARMv7-M B3.2.8 CCR, B3.2.13 SHCSR).
  toonforce::mcu::board::reg(0xE000ED14) |= 1U << 4;                           // CCR.DIV_0_TRP
  toonforce::mcu::board::reg(0xE000ED24) |= (1U << 16) | (1U << 17) | (1U << 18);  // SHCSR enables
#if defined(__ARM_FP)
  // The M4F's FPU is off at reset: grant CP10 and CP11 full access (CPACR, B3.2.20).
  toonforce::mcu::board::reg(0xE000ED88) |= 0xFU << 20;
  asm volatile("dsb\n isb" ::: "memory");
#endif
  toonforce::mcu::board::exit(run_image());
}
