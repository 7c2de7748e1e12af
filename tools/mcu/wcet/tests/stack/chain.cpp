// SPDX-License-Identifier: Apache-2.0
// The static stack bound's hand-made case (test_stack_bound.py): entry -> middle -> deep, where
// deep (deep.s) has no .su line and takes its frame from its disassembly (216 bytes), and
// middle's other callee, leaf, calls libgcc's 64-bit division (__aeabi_ldivmod, then
// __udivmoddi4: no .su lines either). The deepest chain is entry -> middle -> deep: the bound is
// the .su frames of entry and middle plus deep's 216, and leaves out none of them.
#include <cstdint>

extern "C" int deep(int x);

[[gnu::noinline]] std::int64_t leaf(std::int64_t a, std::int64_t b) {
  volatile std::int32_t scratch[4];
  scratch[static_cast<unsigned>(a) & 3U] = static_cast<std::int32_t>(b);
  return a / b + scratch[1];
}

[[gnu::noinline]] int middle(int x) {
  volatile int buffer[16];
  buffer[static_cast<unsigned>(x) & 15U] = x;
  return static_cast<int>(leaf(x, x + 7)) + deep(x) + buffer[3];
}

extern "C" int entry(int x) {
  volatile int local[6];
  local[static_cast<unsigned>(x) % 6U] = x;
  return middle(x) + local[2];
}

// libgcc's __aeabi_ldivmod calls this on a zero divisor.
extern "C" void __aeabi_ldiv0() {
  for (;;) {
  }
}
