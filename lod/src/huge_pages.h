// Large working arrays in memory the kernel may back with 2 MB pages (madvise MADV_HUGEPAGE;
// transparent huge pages in "madvise" mode, Debian's default). A mesh build fills hundreds of MB
// of fresh arrays once each (per-triangle lists, the dual graph, the Morton order); with 4 KB
// pages every first touch is a page fault, and in this machine's virtual machine the faults were
// a fifth of the build's time (bench/mesh_lod: the 17.8 M-triangle build in 22.1 s with every
// page small, 16.4 s with glibc asked to advise all its mappings). Advice only: where the kernel
// has no huge pages to give, or THP is off, nothing changes but the time.
#pragma once

#include <sys/mman.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace tessera::lod::detail {

/// Advises the whole 2 MB pages inside [p, p + bytes) for huge pages (ranges under 4 MB are
/// left alone). Call before the memory is first touched: pages already faulted stay small.
inline void adviseHugePages(const void* p, size_t bytes) {
  constexpr uintptr_t kHuge = uintptr_t(2) << 20;
  if (p == nullptr || bytes < 2 * kHuge) return;
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(p) + kHuge - 1) & ~(kHuge - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(p) + bytes) & ~(kHuge - 1);
  if (end > begin) (void)::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
}

/// `v` empty with fresh storage for `n` elements advised for huge pages (what it held is
/// dropped): for arrays filled by push_back or insert up to a known size.
template <class T, class A>
void reserveHuge(std::vector<T, A>& v, size_t n) {
  std::vector<T, A>().swap(v);
  v.reserve(n);
  adviseHugePages(v.data(), n * sizeof(T));
}

/// `v` holding `n` copies of `value` in fresh storage advised for huge pages (what it held is
/// dropped).
template <class T, class A>
void assignHuge(std::vector<T, A>& v, size_t n, const T& value = T()) {
  reserveHuge(v, n);
  v.assign(n, value);
}

/// An allocator whose value-less construct() default-initialises: resize() of a vector of
/// trivial elements leaves them unwritten instead of zero-filling them on one thread, so a
/// parallel pass that writes every element is also the arrays' first touch (the kernel clears
/// the pages on the writing threads). Constructing from values is as std::allocator's.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  using value_type = T;
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// A builder's large array: resize() does not initialise trivial elements (see above).
template <class T>
using HugeVector = std::vector<T, DefaultInitAllocator<T>>;

/// `v` holding `n` unwritten elements in fresh storage advised for huge pages (what it held is
/// dropped); the caller writes every one of them, in parallel where it is large.
template <class T>
void sizeHuge(HugeVector<T>& v, size_t n) {
  HugeVector<T>().swap(v);
  v.reserve(n);
  adviseHugePages(v.data(), n * sizeof(T));
  v.resize(n);
}

}  // namespace tessera::lod::detail
