// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Heap-allocation counting for tests: proves that code under test (observer steps, runtime
// helpers, generated observers) performs no dynamic allocation.
//
// Link alloc_counter.cpp into a *separate* test executable (CMake: link the OBJECT library
// `obsynth_alloc_counter`). It replaces, for the whole program,
//   - every replaceable global operator new / new[] / delete / delete[] (sized, aligned and
//     nothrow variants included), and
//   - on glibc, and unless a sanitizer owns the allocator (ASan/TSan/MSan), the C allocation
//     functions malloc, calloc, realloc, reallocarray, free, aligned_alloc, posix_memalign,
//     memalign, valloc and pvalloc, forwarding to glibc's __libc_* entry points. This also
//     catches allocations made by C code, by libstdc++ and by Eigen's aligned_malloc.
// Each allocation is counted exactly once (operator new calls the allocator directly, not the
// hooked malloc).
//
//   #include "alloc_counter.hpp"
//   obsynth::test::AllocationCounter counter;   // starts counting now
//   observer.step(dt, u, y);
//   EXPECT_EQ(counter.allocations(), 0u);
//
// Counts are global (all threads) and monotone; AllocationCounter reports the difference
// since its construction (or its last restart()). Keep assertions (which may allocate to
// format messages) outside the measured region, or read the count into a local first.
#pragma once

#include <cstddef>

namespace obsynth::test {

struct AllocationStats {
  std::size_t allocations = 0;    ///< successful allocation calls (new, malloc, realloc, ...)
  std::size_t deallocations = 0;  ///< delete / free of a non-null pointer
  std::size_t bytes = 0;          ///< bytes requested by the counted allocations
};

/// Totals since program start.
AllocationStats allocation_stats() noexcept;

/// true when the C allocation functions (malloc & co.) are counted too, not only operator new.
bool malloc_hooks_active() noexcept;

/// Counts allocations between its construction (or restart()) and the query.
class AllocationCounter {
 public:
  AllocationCounter() noexcept : start_(allocation_stats()) {}
  void restart() noexcept { start_ = allocation_stats(); }
  std::size_t allocations() const noexcept {
    return allocation_stats().allocations - start_.allocations;
  }
  std::size_t deallocations() const noexcept {
    return allocation_stats().deallocations - start_.deallocations;
  }
  std::size_t bytes() const noexcept { return allocation_stats().bytes - start_.bytes; }

 private:
  AllocationStats start_;
};

}  // namespace obsynth::test
