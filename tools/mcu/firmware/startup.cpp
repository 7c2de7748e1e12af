// SPDX-License-Identifier: Apache-2.0
// Reset and fault handling for the mps2 boards: unaligned-access, divide-by-zero and fault
// traps on first, then the stack painted (for its high-water mark), the read-only data, motions
// and .data copied to RAM and .bss zeroed, then run_image(). A fault reports which one, its
// fault status bits and the faulting instruction's address, and ends the run with status 1.
// No C runtime start files (-nostartfiles) and no heap: nothing here or in the image may
// allocate (mps2.ld fails the link if malloc or operator new is linked at all).
#include <cstdint>

#include "board.hpp"
#include "stack_paint.hpp"

extern "C" {
// From mps2.ld.
extern std::uint32_t __data_start, __data_end, __data_load, __bss_start, __bss_end;
extern std::uint32_t __rodata_start, __rodata_end, __rodata_load;
extern std::uint32_t __motion_start, __motion_end, __motion_load;
extern std::uint32_t __init_array_load;
extern std::uint32_t __stack_bottom, __stack_top;
extern void (*__init_array_start[])();
extern void (*__init_array_end[])();

[[noreturn]] void Reset_Handler();
void fault_entry();
[[noreturn]] void toonforce_fault_report(const std::uint32_t* frame);
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
void unexpected() { trap("unexpected exception"); }

// Words of a section from its load address in flash to its place in RAM (element loops: no
// library calls before the sections are in place).
void copy_words(std::uint32_t* dst, std::uint32_t* end, const std::uint32_t* src) {
  while (dst < end) *dst++ = *src++;
}

char* put_hex(char* out, std::uint32_t value) {
  *out++ = '0';
  *out++ = 'x';
  for (int shift = 28; shift >= 0; shift -= 4) *out++ = "0123456789abcdef"[(value >> shift) & 0xFU];
  return out;
}

char* put(char* out, const char* text) {
  while (*text != '\0') *out++ = *text++;
  return out;
}

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
    {Reset_Handler, nmi, fault_entry, fault_entry, fault_entry, fault_entry, nullptr, nullptr, nullptr, nullptr,
     unexpected, unexpected, nullptr, unexpected, SysTick_Handler}};

// A 64-bit division by zero (__aeabi_ldivmod) calls these instead of trapping in hardware;
// Fixed never divides by zero, so reaching one is a bug to stop on.
extern "C" void __aeabi_idiv0() { trap("integer division by zero"); }
extern "C" void __aeabi_ldiv0() { trap("64-bit division by zero"); }
// Without an OS there is nowhere to abort to (std::abort, a failed assert).
extern "C" [[noreturn]] void _exit(int) { trap("_exit called (abort or assert)"); }

// The four faults enter here: the exception frame is on the main stack unless EXC_RETURN
// (in LR) says the process stack (ARMv7-M ARM B1.5.6, B1.5.8); its seventh word is the PC of
// the faulting instruction (a precise fault's).
extern "C" [[gnu::naked]] void fault_entry() {
  asm volatile("tst lr, #4\n"
               "ite eq\n"
               "mrseq r0, msp\n"
               "mrsne r0, psp\n"
               "b toonforce_fault_report\n");
}

// Which fault (IPSR), its status bits (CFSR 0xE000ED28, HFSR 0xE000ED2C: ARMv7-M ARM B3.2.15,
// B3.2.16) by name, and the stacked PC, e.g. "trap: UsageFault UNALIGNED pc 0x00000a3c cfsr
// 0x01000000", then exit status 1: a CTest failure that says what and where.
extern "C" [[noreturn]] void toonforce_fault_report(const std::uint32_t* frame) {
  namespace board = toonforce::mcu::board;
  std::uint32_t ipsr;
  asm volatile("mrs %0, ipsr" : "=r"(ipsr));
  const std::uint32_t cfsr = board::reg(0xE000ED28);
  const std::uint32_t hfsr = board::reg(0xE000ED2C);
  static constexpr const char* kException[] = {"Thread",    "Reset",    "NMI",       "HardFault",
                                               "MemManage", "BusFault", "UsageFault"};
  struct Bit {
    std::uint32_t mask;
    const char* name;
  };
  static constexpr Bit kCfsr[] = {{1U << 0, "IACCVIOL"},     {1U << 1, "DACCVIOL"},   {1U << 3, "MUNSTKERR"},
                                  {1U << 4, "MSTKERR"},      {1U << 8, "IBUSERR"},    {1U << 9, "PRECISERR"},
                                  {1U << 10, "IMPRECISERR"}, {1U << 11, "UNSTKERR"},  {1U << 12, "STKERR"},
                                  {1U << 16, "UNDEFINSTR"},  {1U << 17, "INVSTATE"},  {1U << 18, "INVPC"},
                                  {1U << 19, "NOCP"},        {1U << 24, "UNALIGNED"}, {1U << 25, "DIVBYZERO"}};
  char text[256];
  char* out = put(text, "trap: ");
  out = put(out, (ipsr & 0x1FFU) < 7 ? kException[ipsr & 0x1FFU] : "fault");
  if ((hfsr & (1U << 30)) != 0) out = put(out, " FORCED");
  for (const Bit& bit : kCfsr) {
    if ((cfsr & bit.mask) != 0) out = put(put(out, " "), bit.name);
  }
  out = put_hex(put(out, " pc "), frame[6]);
  out = put_hex(put(out, " cfsr "), cfsr);
  out = put(out, "\n");
  *out = '\0';
  board::write0(text);
  board::exit(1);
}

extern "C" [[noreturn]] void Reset_Handler() {
  // Before anything else: trap every unaligned load or store (CCR.UNALIGN_TRP; LDM, STM, LDRD
  // and STRD fault unaligned whatever it says) and integer division by zero (CCR.DIV_0_TRP),
  // and report MemManage, BusFault and UsageFault as themselves rather than escalated to
  // HardFault (ARMv7-M ARM B3.2.8 CCR, B3.2.13 SHCSR, A3.2.1).
  toonforce::mcu::board::reg(0xE000ED14) |= (1U << 3) | (1U << 4);                 // CCR
  toonforce::mcu::board::reg(0xE000ED24) |= (1U << 16) | (1U << 17) | (1U << 18);  // SHCSR enables
  asm volatile("dsb\n isb" ::: "memory");  // in force from the next instruction (B3.2.8)
  toonforce::mcu::paint_stack_below(toonforce::mcu::board::stack_pointer());
  // Read-only data, motions, init array and .data from their load addresses in flash; .bss zeroed.
  copy_words(&__rodata_start, &__rodata_end, &__rodata_load);
  copy_words(reinterpret_cast<std::uint32_t*>(__init_array_start), reinterpret_cast<std::uint32_t*>(__init_array_end),
             &__init_array_load);
  copy_words(&__motion_start, &__motion_end, &__motion_load);
  copy_words(&__data_start, &__data_end, &__data_load);
  for (std::uint32_t* dst = &__bss_start; dst < &__bss_end;) *dst++ = 0;
  for (auto* f = __init_array_start; f < __init_array_end; ++f) (*f)();

#if defined(__ARM_FP)
  // The M4F's FPU is off at reset: grant CP10 and CP11 full access (CPACR, B3.2.20).
  toonforce::mcu::board::reg(0xE000ED88) |= 0xFU << 20;
  asm volatile("dsb\n isb" ::: "memory");
#endif
  toonforce::mcu::board::exit(run_image());
}
