// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Global allocation hooks for obsynth tests; see alloc_counter.hpp.
#include "alloc_counter.hpp"

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

// Decide whether the C allocation functions can be replaced: glibc exports its allocator as
// __libc_malloc & co., which the replacements forward to. Sanitizers interpose malloc
// themselves, so leave it to them there (operator new is still counted; it then calls the
// sanitizer's malloc).
#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer) || __has_feature(hwaddress_sanitizer)
#define OBSYNTH_ALLOC_UNDER_SANITIZER 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__) || \
    defined(__SANITIZE_HWADDRESS__)
#define OBSYNTH_ALLOC_UNDER_SANITIZER 1
#endif

#if defined(__GLIBC__) && !defined(OBSYNTH_ALLOC_UNDER_SANITIZER) && \
    !defined(OBSYNTH_ALLOC_COUNTER_NO_MALLOC_HOOK)
#define OBSYNTH_ALLOC_HOOK_MALLOC 1
#else
#define OBSYNTH_ALLOC_HOOK_MALLOC 0
#endif

namespace {

// Constant-initialised, so they are usable before any dynamic initialisation runs.
std::atomic<std::size_t> g_allocations{0};
std::atomic<std::size_t> g_deallocations{0};
std::atomic<std::size_t> g_bytes{0};

inline void note_alloc(const void* p, std::size_t n) noexcept {
  if (p != nullptr) {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    g_bytes.fetch_add(n, std::memory_order_relaxed);
  }
}

inline void note_free(const void* p) noexcept {
  if (p != nullptr) g_deallocations.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace

#if OBSYNTH_ALLOC_HOOK_MALLOC
extern "C" {
void* __libc_malloc(std::size_t);
void __libc_free(void*);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);
}

namespace {
inline void* raw_malloc(std::size_t n) noexcept { return __libc_malloc(n); }
inline void raw_free(void* p) noexcept { __libc_free(p); }
inline void* raw_aligned(std::size_t align, std::size_t n) noexcept {
  return __libc_memalign(align, n);
}
}  // namespace

extern "C" {

void* malloc(std::size_t n) noexcept {
  void* p = __libc_malloc(n);
  note_alloc(p, n);
  return p;
}

void free(void* p) noexcept {
  note_free(p);
  __libc_free(p);
}

void* calloc(std::size_t count, std::size_t size) noexcept {
  void* p = __libc_calloc(count, size);
  note_alloc(p, count * size);
  return p;
}

void* realloc(void* old, std::size_t n) noexcept {
  void* p = __libc_realloc(old, n);
  if (p != nullptr) {
    note_alloc(p, n);
    note_free(old);
  } else if (n == 0) {
    note_free(old);  // realloc(p, 0) frees p
  }
  return p;
}

void* reallocarray(void* old, std::size_t count, std::size_t size) noexcept {
  if (size != 0 && count > SIZE_MAX / size) {
    errno = ENOMEM;
    return nullptr;
  }
  return realloc(old, count * size);
}

void* aligned_alloc(std::size_t align, std::size_t n) noexcept {
  void* p = __libc_memalign(align, n);
  note_alloc(p, n);
  return p;
}

void* memalign(std::size_t align, std::size_t n) noexcept {
  void* p = __libc_memalign(align, n);
  note_alloc(p, n);
  return p;
}

int posix_memalign(void** out, std::size_t align, std::size_t n) noexcept {
  if (align < sizeof(void*) || (align & (align - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(align, n);
  if (p == nullptr) return ENOMEM;
  note_alloc(p, n);
  *out = p;
  return 0;
}

void* valloc(std::size_t n) noexcept {
  void* p = __libc_valloc(n);
  note_alloc(p, n);
  return p;
}

void* pvalloc(std::size_t n) noexcept {
  void* p = __libc_pvalloc(n);
  note_alloc(p, n);
  return p;
}

}  // extern "C"

#else  // !OBSYNTH_ALLOC_HOOK_MALLOC

namespace {
inline void* raw_malloc(std::size_t n) noexcept { return std::malloc(n); }
inline void raw_free(void* p) noexcept { std::free(p); }
inline void* raw_aligned(std::size_t align, std::size_t n) noexcept {
  void* p = nullptr;
  if (align < sizeof(void*)) align = sizeof(void*);
  return posix_memalign(&p, align, n) == 0 ? p : nullptr;
}
}  // namespace

#endif  // OBSYNTH_ALLOC_HOOK_MALLOC

namespace {

void* counted_new(std::size_t n) noexcept {
  if (n == 0) n = 1;
  void* p = raw_malloc(n);
  note_alloc(p, n);
  return p;
}

void* counted_new_aligned(std::size_t n, std::align_val_t al) noexcept {
  if (n == 0) n = 1;
  void* p = raw_aligned(static_cast<std::size_t>(al), n);
  note_alloc(p, n);
  return p;
}

void counted_delete(void* p) noexcept {
  note_free(p);
  raw_free(p);
}

void* new_or_fail(void* p) {
  if (p == nullptr) {
#if defined(__cpp_exceptions)
    throw std::bad_alloc();
#else
    std::abort();
#endif
  }
  return p;
}

}  // namespace

void* operator new(std::size_t n) { return new_or_fail(counted_new(n)); }
void* operator new[](std::size_t n) { return new_or_fail(counted_new(n)); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return counted_new(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return counted_new(n); }
void* operator new(std::size_t n, std::align_val_t al) {
  return new_or_fail(counted_new_aligned(n, al));
}
void* operator new[](std::size_t n, std::align_val_t al) {
  return new_or_fail(counted_new_aligned(n, al));
}
void* operator new(std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return counted_new_aligned(n, al);
}
void* operator new[](std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return counted_new_aligned(n, al);
}

void operator delete(void* p) noexcept { counted_delete(p); }
void operator delete[](void* p) noexcept { counted_delete(p); }
void operator delete(void* p, std::size_t) noexcept { counted_delete(p); }
void operator delete[](void* p, std::size_t) noexcept { counted_delete(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { counted_delete(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { counted_delete(p); }
void operator delete(void* p, std::align_val_t) noexcept { counted_delete(p); }
void operator delete[](void* p, std::align_val_t) noexcept { counted_delete(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { counted_delete(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { counted_delete(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  counted_delete(p);
}
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  counted_delete(p);
}

namespace obsynth::test {

AllocationStats allocation_stats() noexcept {
  AllocationStats s;
  s.allocations = g_allocations.load(std::memory_order_relaxed);
  s.deallocations = g_deallocations.load(std::memory_order_relaxed);
  s.bytes = g_bytes.load(std::memory_order_relaxed);
  return s;
}

bool malloc_hooks_active() noexcept { return OBSYNTH_ALLOC_HOOK_MALLOC != 0; }

}  // namespace obsynth::test
