// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A single-writer, many-reader snapshot without locks (a sequence lock): the servo thread
/// publishes a trivially copyable value every tick and never waits; readers on other threads
/// retry while a write is in progress. The data live in atomic words, so there is no data race
/// in the C++ sense (Boehm, "Can seqlocks get along with programming language memory models?",
/// 2012): readers see either a whole old value or a whole new one.
///
/// The words are stored with release and loaded with acquire instead of Boehm's two fences:
/// a reader that loads a word of a newer write then reads the sequence at least as new as
/// that write's odd value (the odd store happens before its word stores), so it retries. On
/// x86-64, the Omni's platform, these are the same plain moves as relaxed ones, and
/// ThreadSanitizer, which does not model standalone fences, checks them.

#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <thread>
#include <type_traits>

namespace toonforce::omni {

template <class T>
class SeqLock {
  static_assert(std::is_trivially_copyable_v<T>);
  static constexpr std::size_t kWords = (sizeof(T) + sizeof(std::uint64_t) - 1) / sizeof(std::uint64_t);

 public:
  /// Writer side (one thread only): wait-free.
  void store(const T& value) noexcept {
    std::array<std::uint64_t, kWords> words{};
    std::memcpy(words.data(), &value, sizeof(T));
    const std::uint64_t seq = sequence_.load(std::memory_order_relaxed);
    sequence_.store(seq + 1, std::memory_order_relaxed);  // odd: a write is in progress
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(words[i], std::memory_order_release);
    sequence_.store(seq + 2, std::memory_order_release);
  }

  /// Reader side: false when a write overlapped (try again).
  bool try_load(T& out) const noexcept {
    const std::uint64_t before = sequence_.load(std::memory_order_acquire);
    if ((before & 1U) != 0) return false;
    std::array<std::uint64_t, kWords> words{};
    for (std::size_t i = 0; i < kWords; ++i) words[i] = words_[i].load(std::memory_order_acquire);
    if (sequence_.load(std::memory_order_relaxed) != before) return false;
    std::memcpy(static_cast<void*>(&out), words.data(), sizeof(T));  // T is trivially copyable
    return true;
  }

  /// Reader side: the latest complete value (retries; never call it from the writer's thread).
  T load() const noexcept {
    T out{};
    while (!try_load(out)) std::this_thread::yield();
    return out;
  }

  /// How many values have been stored.
  std::uint64_t version() const noexcept { return sequence_.load(std::memory_order_acquire) / 2; }

 private:
  std::atomic<std::uint64_t> sequence_{0};
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
};

}  // namespace toonforce::omni
