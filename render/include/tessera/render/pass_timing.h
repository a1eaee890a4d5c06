// Whether the frame's passes time their GL work (RenderStats' *_ms, the passes' returned
// milliseconds). Timing a pass waits for the GL to finish it (glFinish), which on a real GPU
// serialises the CPU and the GPU at every pass, so it is off unless asked for: the benchmarks
// and tessera-render --stats ask. Off, the passes report 0 ms. Process-wide; set it before
// rendering (it may change between frames).
#pragma once

#include <atomic>

namespace tessera::render {

namespace detail {
inline std::atomic<bool> gTimePasses{false};
}  // namespace detail

inline void timePasses(bool on) {
  detail::gTimePasses.store(on, std::memory_order_relaxed);
}
inline bool timingPasses() {
  return detail::gTimePasses.load(std::memory_order_relaxed);
}

}  // namespace tessera::render
