// SPDX-License-Identifier: Apache-2.0
// TOONFORCE_LOOP_BOUND from the real header, compiled for the Cortex-M3 by the test: the loop's
// bound comes from the template parameter; the unused function, which --gc-sections drops,
// takes its annotation with it.
#include <cstdint>

#include "toonforce/math/loop_bound.hpp"

template <std::uint32_t kN>
[[gnu::noinline]] std::uint32_t sum(const std::uint32_t* values, std::uint32_t n) {
  std::uint32_t total = 0;
  for (std::uint32_t i = 0; i < n; ++i) {
    TOONFORCE_LOOP_BOUND(kN);
    total += values[i] * values[i];
  }
  return total;
}

[[gnu::noinline]] std::uint32_t unused(const std::uint32_t* values, std::uint32_t n) {
  std::uint32_t total = 1;
  for (std::uint32_t i = 0; i < n; ++i) {
    TOONFORCE_LOOP_BOUND(5);
    total ^= values[i] + i;
  }
  return total;
}

volatile std::uint32_t g_values[12];
volatile std::uint32_t g_n;

constexpr std::uint32_t kCount = 12;

extern "C" std::uint32_t entry() {
  std::uint32_t copy[kCount];
  for (std::uint32_t i = 0; i < kCount; ++i) {
    TOONFORCE_LOOP_BOUND(kCount);
    copy[i] = g_values[i];
  }
  return sum<kCount>(copy, g_n);
}
