// Milliseconds of GL work, for the passes' stated costs (internal to the render library), when
// asked for (pass_timing.h).
#pragma once

#include <chrono>

#include <tessera/render/pass_timing.h>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

namespace tessera::render {

/// Milliseconds since the previous lap (or construction), with the GL work finished; 0 without
/// waiting when pass timing is off.
class GpuLap {
 public:
  double operator()() {
    if (!timingPasses()) return 0.0;
    glFinish();
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - mStart).count();
    mStart = now;
    return ms;
  }

 private:
  std::chrono::steady_clock::time_point mStart = std::chrono::steady_clock::now();
};

}  // namespace tessera::render
