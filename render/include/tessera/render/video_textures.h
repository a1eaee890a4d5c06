// Video insets on a view: one receiver (media/video_packet.h: assembler, H.264
// decoder, the policy that keeps the picture good) and one RGBA texture per remote site's
// stream. Render nodes feed it the video packets of each frame message, the console and sites
// those the master forwards; the scene overlay (scene_overlay.h) draws the textures on the
// VIDEO_INSET nodes. Only the streams the view shows are decoded (setShown: the others' packets
// are counted and skipped, and a stream that comes into view starts at its next key or
// refresh), so a tile without insets costs nothing but receiving.
//
// A GL 4.5 context must be current for upload() and the object's destruction. Texture
// addresses stay valid for the object's life (a texture that changes size is replaced in
// place). Not thread-safe.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>

#include <tessera/media/video_packet.h>
#include <tessera/render/gl_objects.h>

namespace tessera::render {

struct VideoTextureStats {
  uint64_t packets = 0, refused = 0;  ///< packets received; refused by their checks
  uint64_t decoded = 0, skipped = 0, errors = 0, lost = 0;  ///< all streams together
  uint64_t uploads = 0;
  std::string last_problem;  ///< the last refusal or decoding error, for messages
};

class VideoTextures {
 public:
  /// Streams this view keeps at most (sources beyond are refused).
  static constexpr size_t kMaxStreams = 64;

  VideoTextures();
  ~VideoTextures();
  VideoTextures(const VideoTextures&) = delete;
  VideoTextures& operator=(const VideoTextures&) = delete;

  /// One video packet's bytes (from outside: checked). Returns why it is refused, if it is.
  std::optional<std::string> receive(std::span<const uint8_t> bytes);
  /// The sources whose insets this view shows (scene_overlay.h shownVideoSources()).
  void setShown(const std::set<uint32_t>& sources);
  /// Uploads the pictures decoded since the last call. Returns true when a texture was made
  /// or changed size: an overlay built before must be rebuilt (SceneOverlay::invalidate()).
  bool upload();
  /// The texture of `source`'s stream, or null before its first picture.
  const GlTexture* texture(uint32_t source) const;

  VideoTextureStats stats() const;

 private:
  struct Stream {
    media::VideoReceiver receiver;
    GlTexture texture;
    uint64_t uploaded = 0;  // the receiver's generation in the texture
  };
  std::map<uint32_t, std::unique_ptr<Stream>> mStreams;
  std::set<uint32_t> mShown;
  VideoTextureStats mStats;
};

}  // namespace tessera::render
