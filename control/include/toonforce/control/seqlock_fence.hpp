// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The two fences of a sequence lock whose data are plain bytes shared with another process
/// (the guardian's page, the live-scene mailbox): the writer's, between making the sequence odd
/// and writing the data; the reader's, between copying the data and reading the sequence again.
///
/// ThreadSanitizer does not model standalone fences (GCC refuses them under -fsanitize=thread
/// with -Wtsan). On x86-64, the only target of the ThreadSanitizer build, an acquire or a
/// release fence emits no instruction: it only keeps the compiler from moving memory accesses
/// across it, which a signal fence does as well. So under ThreadSanitizer the fence is a signal
/// fence, and the code generated is the product's.

#include <atomic>

namespace toonforce {

#if defined(__SANITIZE_THREAD__)
#if !defined(__x86_64__)
#error "the ThreadSanitizer build's seqlock fences are compiler barriers, exact on x86-64 only"
#endif
inline void seqlock_write_fence() noexcept { std::atomic_signal_fence(std::memory_order_release); }
inline void seqlock_read_fence() noexcept { std::atomic_signal_fence(std::memory_order_acquire); }
#else
inline void seqlock_write_fence() noexcept { std::atomic_thread_fence(std::memory_order_release); }
inline void seqlock_read_fence() noexcept { std::atomic_thread_fence(std::memory_order_acquire); }
#endif

}  // namespace toonforce
