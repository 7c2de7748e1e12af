// SPDX-License-Identifier: Apache-2.0
// Allocates once: its link must fail (mps2.ld: the images have no heap). Built only by the
// CTest test mcu_m3_heap_link_fails, which expects exactly that failure. The pointer escapes
// into a volatile global, so the compiler cannot elide the allocation (C++14 [expr.new]/10).
int* volatile g_allocated = nullptr;

int run_image() {  // called by startup.cpp's reset handler
  g_allocated = new int(42);
  return *g_allocated == 42 ? 0 : 1;
}
