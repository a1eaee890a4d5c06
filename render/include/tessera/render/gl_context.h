// An OpenGL 4.5 core context: headless through EGL on Mesa's surfaceless platform (tests, CI,
// headless wall nodes). The context is current on the creating thread for its whole life.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>

namespace tessera::render {

/// No usable GL (no EGL, no 4.5 core context, a shader that does not compile). Says which.
class RenderError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class GlContext {
 public:
  /// Creates a surfaceless EGL display and a GL 4.5 core context and makes it current.
  static std::unique_ptr<GlContext> createHeadless();
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;
  /// GL_RENDERER and GL_VERSION, e.g. "llvmpipe (LLVM 15.0.6, 256 bits), 4.5 (Core Profile) Mesa".
  std::string description() const;

 private:
  GlContext() = default;
  void* mDisplay = nullptr;
  void* mContext = nullptr;
};

}  // namespace tessera::render
