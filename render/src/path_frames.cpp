#include <tessera/render/path_frames.h>

#include <cmath>
#include <cstdio>

#include <tessera/core/check.h>
#include <tessera/render/gl_context.h>
#include <tessera/sync/camera_state.h>

namespace tessera::render {

size_t pathFrameCount(const config::CameraPath& path, double fps) {
  TESSERA_CHECK(std::isfinite(fps) && fps > 0.0, "render::pathFrameCount(): fps > 0");
  // A hair of tolerance, so 1.375 s at 8 fps is 12 frames whatever the rounding of 1.375 * 8.
  const double n = std::floor(sync::pathDuration(path) * fps + 1e-9) + 1.0;
  if (!(n <= double(kMaxPathFrames)))
    throw RenderError("render::pathFrameCount(): " + std::to_string(sync::pathDuration(path)) +
                      " s at " + std::to_string(fps) + " fps is more than " +
                      std::to_string(kMaxPathFrames) + " frames");
  return size_t(n);
}

void forEachPathFrame(const config::CameraPath& path, double fps,
                      const std::function<void(size_t, double, const config::Camera&)>& frame) {
  const size_t n = pathFrameCount(path, fps);
  for (size_t i = 0; i < n; ++i) {
    const double t = double(i) / fps;
    // The camera as the wall's scene graph carries it (sync/camera_state.h: a float view and a
    // roll), so a frame is the master's frame at the same time, pixel for pixel.
    frame(i, t, sync::decodeCamera(sync::encodeCamera(sync::cameraAt(path, t))));
  }
}

std::filesystem::path framePngPath(const std::filesystem::path& dir, size_t frame) {
  char name[32];
  std::snprintf(name, sizeof name, "frame-%06zu.png", frame);
  return dir / name;
}

}  // namespace tessera::render
