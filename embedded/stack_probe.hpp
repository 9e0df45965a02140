// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Stack high-water measurement by painting, for bare-metal Cortex-M test programs.
//
//   auto probe = obsynth_embedded::stack_paint(4096);   // paint 4 KiB below the current SP
//   observer_step(...);                                 // a non-inlined call
//   std::size_t used = obsynth_embedded::stack_high_water(probe);
//
// stack_paint fills the free stack below the caller's SP with a pattern; stack_high_water finds
// the lowest word that was overwritten, i.e. the deepest stack use (frames of every callee,
// including library calls) since painting, in bytes below the caller's SP. Both are
// always_inline so that they measure relative to the caller's own stack pointer. AAPCS has no
// red zone and these programs enable no interrupts, so the memory below SP is free.
// On hosted builds (not bare-metal ARM) both are no-ops and the result is 0.
#pragma once

#include <cstddef>
#include <cstdint>

namespace obsynth_embedded {

struct StackProbe {
  std::uintptr_t top = 0;     // caller's SP when painting
  std::uintptr_t bottom = 0;  // lowest painted address
};

#if defined(__arm__) && !defined(__linux__)
constexpr bool kStackProbeAvailable = true;
constexpr std::uint32_t kStackPaint = 0xC5A5C5A5u;

__attribute__((always_inline)) inline StackProbe stack_paint(std::size_t bytes) noexcept {
  std::uintptr_t sp = 0;
  __asm__ volatile("mov %0, sp" : "=r"(sp));
  StackProbe p;
  p.top = sp & ~static_cast<std::uintptr_t>(3);
  p.bottom = p.top - (bytes & ~static_cast<std::size_t>(3));
  for (std::uintptr_t a = p.bottom; a < p.top; a += 4) {
    *reinterpret_cast<volatile std::uint32_t*>(a) = kStackPaint;
  }
  return p;
}

__attribute__((always_inline)) inline std::size_t stack_high_water(const StackProbe& p) noexcept {
  for (std::uintptr_t a = p.bottom; a < p.top; a += 4) {
    if (*reinterpret_cast<volatile std::uint32_t*>(a) != kStackPaint) {
      return static_cast<std::size_t>(p.top - a);
    }
  }
  return 0;
}
#else
constexpr bool kStackProbeAvailable = false;
inline StackProbe stack_paint(std::size_t) noexcept { return {}; }
inline std::size_t stack_high_water(const StackProbe&) noexcept { return 0; }
#endif

}  // namespace obsynth_embedded
