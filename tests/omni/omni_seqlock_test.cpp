// SPDX-License-Identifier: Apache-2.0
// The Omni backend's snapshot between the vendor's servo thread and the application
// (hal/omni seqlock.hpp): a reader racing a writer that never waits sees only whole values,
// in the order they were stored. Run under ThreadSanitizer too (CMakePresets.json, tsan),
// which checks the words' ordering without fences.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>

#include "toonforce/hal/omni/seqlock.hpp"

namespace toonforce::omni {
namespace {

// Five words (not a multiple of anything the lock might special-case), every one the same
// number in a whole value; a torn read mixes two numbers.
struct Snapshot {
  std::array<std::uint64_t, 5> words{};
};

TEST(OmniSeqLock, AReaderRacingTheWriterSeesOnlyWholeValuesInOrder) {
  SeqLock<Snapshot> lock;
  constexpr std::uint64_t kStores = 200'000;
  std::atomic<bool> reader_started{false};
  std::thread writer([&] {
    while (!reader_started.load(std::memory_order_acquire)) std::this_thread::yield();
    for (std::uint64_t n = 1; n <= kStores; ++n) {
      Snapshot s;
      s.words.fill(n);
      lock.store(s);
    }
  });
  std::uint64_t last = 0;
  std::uint64_t torn = 0;
  std::uint64_t backwards = 0;
  std::uint64_t retries = 0;
  reader_started.store(true, std::memory_order_release);
  while (last < kStores) {
    Snapshot s;
    if (!lock.try_load(s)) {
      ++retries;
      continue;
    }
    for (std::uint64_t w : s.words) torn += w != s.words[0] ? 1U : 0U;
    backwards += s.words[0] < last ? 1U : 0U;
    last = s.words[0];
  }
  writer.join();
  EXPECT_EQ(torn, 0U);
  EXPECT_EQ(backwards, 0U);
  EXPECT_EQ(lock.version(), kStores);
  EXPECT_EQ(lock.load().words[0], kStores);
  RecordProperty("retries", static_cast<int>(retries));
}

}  // namespace
}  // namespace toonforce::omni
