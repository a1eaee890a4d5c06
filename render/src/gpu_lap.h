// Milliseconds of GL work, for the passes' stated costs (internal to the render library).
#pragma once

#include <chrono>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

namespace tessera::render {

/// Milliseconds since the previous lap (or construction), with the GL work finished.
class GpuLap {
 public:
  double operator()() {
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
