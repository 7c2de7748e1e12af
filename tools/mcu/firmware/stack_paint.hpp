// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The stack's high-water mark by painting: fill the unused stack with a pattern, run, then
/// find the deepest word that no longer holds it. Exact for what ran, as long as no code
/// happens to store the pattern itself (0xCDCDCDCD: not a plausible pointer, force or count).

#include <cstddef>
#include <cstdint>

extern "C" std::uint32_t __stack_bottom, __stack_top;

namespace toonforce::mcu {

inline constexpr std::uint32_t kStackPaint = 0xCDCD'CDCDU;

/// Paints from the bottom of the stack up to 64 bytes below `sp` (the caller's own frame is
/// above that and in use). `optimize("no-tree-loop-distribute-patterns")`: no memset call.
[[gnu::noinline, gnu::optimize("no-tree-loop-distribute-patterns")]] inline void paint_stack_below(
    std::uint32_t sp) noexcept {
  auto* const end = reinterpret_cast<volatile std::uint32_t*>(sp - 64);
  for (auto* p = reinterpret_cast<volatile std::uint32_t*>(&__stack_bottom); p < end; ++p) *p = kStackPaint;
}

/// Bytes between `sp` and the deepest word written since the paint.
inline std::uint32_t stack_used_below(std::uint32_t sp) noexcept {
  const auto* p = reinterpret_cast<const volatile std::uint32_t*>(&__stack_bottom);
  while (reinterpret_cast<std::uintptr_t>(p) < sp && *p == kStackPaint) ++p;
  return sp - static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(p));
}

/// Words a window's paint and scan take per loop iteration. An image paints and scans a window
/// around every counted tick; under QEMU each pass of a loop is a translation block of its
/// own, which the coverage run logs (`-d exec,nochain`), so eight words a pass make that a
/// quarter as many lines as the tick's own.
inline constexpr std::uint32_t kPaintGroup = 8;

/// Paints the `bytes` below `sp` (unused stack: the caller's own frame is above `sp`);
/// `bytes` is a whole number of groups.
[[gnu::noinline, gnu::optimize("no-tree-loop-distribute-patterns")]] inline void paint_window(
    std::uint32_t sp, std::uint32_t bytes) noexcept {
  auto* const end = reinterpret_cast<volatile std::uint32_t*>(sp);
  for (auto* p = reinterpret_cast<volatile std::uint32_t*>(sp - bytes); p < end; p += kPaintGroup) {
    p[0] = kStackPaint;  // (written out: the images' -O2 does not unroll the loop it would be)
    p[1] = kStackPaint;
    p[2] = kStackPaint;
    p[3] = kStackPaint;
    p[4] = kStackPaint;
    p[5] = kStackPaint;
    p[6] = kStackPaint;
    p[7] = kStackPaint;
  }
}

/// Bytes below `sp` written since paint_window(sp, bytes): the deepest a call made from a
/// frame whose stack pointer is `sp` went. `bytes` when it may have gone deeper. Whole groups
/// still painted are passed with one test each (their words' differences from the paint
/// OR-ed), then the group that holds the deepest written word word by word.
[[gnu::noinline]] inline std::uint32_t used_in_window(std::uint32_t sp, std::uint32_t bytes) noexcept {
  const auto* p = reinterpret_cast<const volatile std::uint32_t*>(sp - bytes);
  const auto* const end = reinterpret_cast<const volatile std::uint32_t*>(sp);
  while (end - p >= static_cast<std::ptrdiff_t>(kPaintGroup) &&
         ((p[0] ^ kStackPaint) | (p[1] ^ kStackPaint) | (p[2] ^ kStackPaint) | (p[3] ^ kStackPaint) |
          (p[4] ^ kStackPaint) | (p[5] ^ kStackPaint) | (p[6] ^ kStackPaint) | (p[7] ^ kStackPaint)) == 0) {
    p += kPaintGroup;
  }
  while (p < end && *p == kStackPaint) ++p;
  return sp - static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(p));
}

/// The program's high-water mark: bytes from the top of the stack to the deepest written word.
inline std::uint32_t stack_high_water() noexcept {
  return stack_used_below(static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(&__stack_top)));
}

}  // namespace toonforce::mcu
