// Video insets: where a site's pictures come from (tessera-site --video):
//   "test"         the generated test pattern (video_pattern.h), its frame number and the system
//                  clock burned in at the moment it is grabbed
//   /dev/videoN    a V4L2 camera through libavdevice's video4linux2 input, at the asked size and
//                  rate when the camera offers them; a capture thread of its own keeps the latest
//                  picture, so grab() never waits for the camera
//   anything else  a video file FFmpeg reads (libavformat), decoded on demand at the pace grab()
//                  is called, from the start again at its end
// Pictures come out RGBA at the asked size (libswscale scales what the source has).
#pragma once

#include <memory>
#include <string>

#include <tessera/media/video_codec.h>

namespace tessera::media {

class VideoSource {
 public:
  virtual ~VideoSource() = default;
  /// The next picture into `out` (width x height); false when there is no new one yet (a camera
  /// between frames). Throws VideoError when the source failed for good (a camera unplugged).
  virtual bool grab(VideoPicture& out) = 0;
  /// What it is, for messages ("test pattern 640x480", "camera /dev/video0 (yuyv422 640x480)").
  virtual std::string describe() const = 0;
};

/// Opens `spec` as above. Throws VideoError naming the file or device and what failed ("media::
/// openVideoSource(): /dev/video0: No such file or directory").
std::unique_ptr<VideoSource> openVideoSource(const std::string& spec, int width, int height,
                                             double fps);

}  // namespace tessera::media
