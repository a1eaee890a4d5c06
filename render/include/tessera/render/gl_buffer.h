// A GL buffer object as a move-only value (resources follow their owner): created and destroyed only with
// its context current on the calling thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>

namespace tessera::render {

class GlBuffer {
 public:
  GlBuffer() = default;
  /// Immutable storage of `bytes` (at least 16), filled from `data` when not null, with GL
  /// storage `flags` (0: written by the GPU and by clear() only). Costs one copy of `bytes` into
  /// the driver.
  GlBuffer(size_t bytes, const void* data, uint32_t flags = 0);
  ~GlBuffer();
  GlBuffer(GlBuffer&& o) noexcept : mName(std::exchange(o.mName, 0)), mBytes(o.mBytes) {}
  GlBuffer& operator=(GlBuffer&& o) noexcept {
    std::swap(mName, o.mName);
    std::swap(mBytes, o.mBytes);
    return *this;
  }
  GlBuffer(const GlBuffer&) = delete;
  GlBuffer& operator=(const GlBuffer&) = delete;

  uint32_t name() const { return mName; }
  size_t bytes() const { return mBytes; }
  /// Sets every 32-bit word to `word`.
  void clear(uint32_t word);
  /// Copies `bytes` from `offset` into `out` (waits for the GL work that writes it).
  void read(size_t offset, size_t bytes, void* out) const;
  explicit operator bool() const { return mName != 0; }

 private:
  uint32_t mName = 0;
  size_t mBytes = 0;
};

}  // namespace tessera::render
