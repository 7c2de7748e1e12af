// SPDX-License-Identifier: Apache-2.0
#pragma once
// Counts heap allocations made through operator new on this thread (the test binary replaces
// the global operator new), so a test can assert that a tick allocates nothing, after Drake's
// LimitMalloc.
#include <cstddef>

namespace toonforce::test {

/// Allocations on this thread since it started.
std::size_t allocation_count() noexcept;

/// Counts allocations made during its lifetime.
class AllocationScope {
 public:
  AllocationScope() noexcept : start_(allocation_count()) {}
  std::size_t count() const noexcept { return allocation_count() - start_; }

 private:
  std::size_t start_;
};

}  // namespace toonforce::test
