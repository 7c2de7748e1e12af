// SPDX-License-Identifier: Apache-2.0
// entry's frame grows with its argument (alloca): -fstack-usage says "dynamic" (refused).
extern "C" int entry(unsigned n) {
  auto* p = static_cast<volatile char*>(__builtin_alloca(n + 1));
  p[n] = 1;
  return p[0];
}
