// The frames of a camera path (sync/camera_path.h) at a frame rate, for movies and PNG
// sequences of a path (tessera-render --path with --movie or --frames-dir): frame i shows the
// camera at t = i / fps seconds, from 0 to the path's duration, as the master plays a path.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>

#include <tessera/sync/camera_path.h>

namespace tessera::render {

/// The most frames a path gives (an hour at 240 fps, and more than a PNG sequence's 6 digits).
constexpr size_t kMaxPathFrames = 999999;

/// Frames at `fps` over [0, pathDuration(path)]: floor(duration * fps) + 1 (a path of one
/// keyframe at time 0: one frame). Throws RenderError when that is more than kMaxPathFrames.
/// Precondition (TESSERA_CHECK): fps finite and > 0.
size_t pathFrameCount(const config::CameraPath& path, double fps);

/// Calls `frame(i, t, camera)` for every frame in order, camera = cameraAt(path, t) as the scene
/// graph carries it to the wall (sync::decodeCamera(sync::encodeCamera())), so frame i is the
/// master's frame i of the same path (tessera-master --path) pixel for pixel. Precondition
/// (TESSERA_CHECK): a validated path (sync::loadCameraPath), fps as pathFrameCount().
void forEachPathFrame(const config::CameraPath& path, double fps,
                      const std::function<void(size_t, double, const config::Camera&)>& frame);

/// Frame i's file of a PNG sequence: DIR/frame-000042.png (six digits, from 0).
std::filesystem::path framePngPath(const std::filesystem::path& dir, size_t frame);

}  // namespace tessera::render
