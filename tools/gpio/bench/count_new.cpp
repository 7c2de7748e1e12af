// SPDX-License-Identifier: Apache-2.0
// Replaces the global operator new to count calls on this thread (how many allocations one
// GPIO call makes). In its own translation unit so the compiler does not inline the
// replacement next to its callers and then warn about malloc/free pairing.
#include <cstddef>
#include <cstdlib>
#include <new>

namespace {
thread_local std::size_t g_new_calls = 0;
}  // namespace

namespace toonforce::bench {
std::size_t new_calls() noexcept { return g_new_calls; }
}  // namespace toonforce::bench

void* operator new(std::size_t size) {
  ++g_new_calls;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) {
  ++g_new_calls;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
