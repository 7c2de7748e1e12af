// SPDX-License-Identifier: Apache-2.0
#pragma once
/// TOONFORCE_LOOP_BOUND(n), placed in a loop's body: that body runs at most n times each time the
/// loop is entered, n a constant expression of the code (a template parameter, an array's size,
/// the digits of a type), never a number typed beside it. On an Arm target it emits the pair
/// (address of this point, n) into the non-allocated ELF section .toonforce.loop_bounds, where
/// the worst-case analyser (tools/mcu/wcet) finds it and bounds the innermost loop of
/// the linked image that holds that address. It emits no instruction; on any other target, and
/// in constant evaluation, it is nothing. A loop the compiler unrolls completely leaves an
/// annotation that no loop holds: the analyser ignores it. The pair's section is linked to the
/// code's (SHF_LINK_ORDER, flag "o"), so --gc-sections drops it with a function it drops, and
/// keeps it without keeping that function.

#include <cstdint>
#include <type_traits>

#if defined(__arm__) && defined(__GNUC__)
#define TOONFORCE_LOOP_BOUND(n)                                                                       \
  do {                                                                                                \
    if (!std::is_constant_evaluated()) {                                                              \
      asm volatile(".Ltoonforce_loop%=:\n\t"                                                          \
                   ".pushsection .toonforce.loop_bounds,\"o\",%%progbits,.Ltoonforce_loop%=\n\t"      \
                   ".word .Ltoonforce_loop%=, %c0\n\t.popsection" ::"i"(                              \
                       std::integral_constant<std::uint32_t, static_cast<std::uint32_t>(n)>::value)); \
    }                                                                                                 \
  } while (false)
#else
#define TOONFORCE_LOOP_BOUND(n)                                                                     \
  do {                                                                                              \
    static_cast<void>(std::integral_constant<std::uint32_t, static_cast<std::uint32_t>(n)>::value); \
  } while (false)
#endif
