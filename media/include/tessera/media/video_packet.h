// Video insets: H.264 access units cut into chunks for the site link (one chunk per
// site message, so no message nears kMaxSiteMessageBytes) and for the cluster link (the master
// forwards chunks to the render nodes in its frame messages). Little-endian, a 16-byte header,
// then the chunk's bytes:
//
//   offset size  field
//   0      1     version (kVideoPacketVersion)
//   1      1     flags: bit 0 = the access unit is a key (decodable from here); the rest 0
//   2      2     site: the sender's participant id (the master rewrites it to the id the link
//                authenticated before forwarding; a site's own value is never trusted)
//   4      4     frame: +1 per access unit, wrapping; gaps are lost access units
//   8      1     chunk index, 0..count-1
//   9      1     chunk count, 1..kMaxVideoChunks
//   10     2     width, pixels (the stream's picture size, for the inset's aspect before decoding)
//   12     2     height, pixels
//   14     2     payload size, bytes: 1..kMaxVideoChunkBytes and exactly the rest of the packet
//   16     n     the chunk of the access unit (Annex B)
//
// decodeVideoPacket() checks every field before anything else looks at it; the assembler then
// bounds what a stream may hold (one access unit of at most kMaxVideoChunks chunks in flight).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <tessera/media/video_codec.h>

namespace tessera::media {

constexpr uint8_t kVideoPacketVersion = 1;
constexpr size_t kVideoHeaderBytes = 16;
/// A chunk's payload: 16000 bytes, so a chunk with its envelopes stays far below the site
/// link's 128 KiB message limit and one large key frame does not hog a link for long.
constexpr size_t kMaxVideoChunkBytes = 16000;
/// Chunks in one access unit: 64 x 16000 bytes = 1 MB, 8 s of a 1 Mbit/s stream.
constexpr int kMaxVideoChunks = 64;
constexpr size_t kMaxVideoPacketBytes = kVideoHeaderBytes + kMaxVideoChunkBytes;

struct VideoPacket {
  uint16_t site = 0;
  uint32_t frame = 0;
  bool key = false;
  uint8_t chunk = 0, chunks = 1;
  uint16_t width = 0, height = 0;
  std::vector<uint8_t> payload;
};

/// The packet's bytes. Precondition (TESSERA_CHECK): 1..kMaxVideoChunkBytes of payload, chunk
/// < chunks <= kMaxVideoChunks.
std::vector<uint8_t> encodeVideoPacket(const VideoPacket& packet);

/// Parses and checks one packet. Returns why it is refused ("video packet: payload size 900
/// but 12 bytes follow the header"), or std::nullopt with `out` filled.
std::optional<std::string> decodeVideoPacket(std::span<const uint8_t> bytes, VideoPacket& out);

/// The site field of a packet's bytes set to `site` (what the master forwards). Precondition:
/// bytes that decodeVideoPacket() accepted.
void setVideoPacketSite(std::vector<uint8_t>& bytes, uint16_t site);

/// A stream's sending end: encodes pictures and cuts each access unit into packets.
class VideoSender {
 public:
  VideoSender(const VideoSettings& settings, uint16_t site);

  /// Encodes one picture; returns its packets' bytes (empty when the encoder made nothing).
  std::vector<std::vector<uint8_t>> send(const VideoPicture& picture);
  VideoEncoder& encoder() { return mEncoder; }
  uint32_t frames() const { return mFrame; }

 private:
  VideoEncoder mEncoder;
  uint16_t mSite;
  uint32_t mFrame = 0;
};

/// Joins one stream's chunks into access units. Chunks of one access unit may come in any
/// order; an access unit is given up when a chunk of a later one arrives first (it lost a
/// chunk), and chunks of earlier access units are ignored. Holds at most one access unit.
class VideoAssembler {
 public:
  struct Unit {
    uint32_t frame = 0;
    bool key = false;
    bool after_gap = false;  ///< access units were lost since the previous whole one
    int width = 0, height = 0;
    std::vector<uint8_t> bytes;
  };
  /// A checked packet; returns the access unit it completes, if it does.
  std::optional<Unit> add(const VideoPacket& packet);
  uint64_t lost() const { return mLost; }  ///< access units given up or never seen

 private:
  bool mStarted = false, mHaveWhole = false;
  uint32_t mFrame = 0;      ///< the access unit being joined
  uint32_t mLastWhole = 0;  ///< the last one completed
  uint8_t mChunks = 0;
  bool mKey = false;
  int mWidth = 0, mHeight = 0;
  std::vector<std::vector<uint8_t>> mParts;
  int mHave = 0;
  uint64_t mLost = 0;
};

struct VideoReceiverStats {
  uint64_t packets = 0, units = 0, decoded = 0;
  uint64_t skipped = 0;  ///< access units not decoded: not shown, or waiting for a key
  uint64_t errors = 0;   ///< access units the decoder refused or made a corrupt picture of
  uint64_t lost = 0;     ///< access units lost (gaps, given-up chunks)
  std::string last_error;
};

/// One stream's receiving end (a render node's, the console's, a site's): the assembler, the
/// decoder and the policy that keeps the picture good. While the stream is not shown, its
/// access units are not decoded; when it is shown again, or after a lost access unit or a
/// decoding error, nothing is decoded until the next key (at most refresh_s away), so no
/// smeared picture ever shows: picture() is the last good one until then.
class VideoReceiver {
 public:
  /// Whether the stream is shown (its inset is in view). Not shown: packets are only counted.
  void setShown(bool shown);
  /// A checked packet of this stream. Returns true when picture() changed.
  bool receive(const VideoPacket& packet);

  const VideoPicture& picture() const { return mDecoder.picture(); }
  /// +1 each time picture() changes.
  uint64_t generation() const { return mGeneration; }
  /// The stream's picture size as its packets say (0 before any).
  int width() const { return mWidth; }
  int height() const { return mHeight; }
  bool waitingForKey() const { return mNeedKey; }
  const VideoReceiverStats& stats() const { return mStats; }

 private:
  VideoAssembler mAssembler;
  VideoDecoder mDecoder;
  bool mShown = true, mNeedKey = true;
  uint64_t mGeneration = 0;
  int mWidth = 0, mHeight = 0;
  VideoReceiverStats mStats;
};

}  // namespace tessera::media
