#include <tessera/media/video_packet.h>

#include <algorithm>

#include <tessera/core/check.h>

#include "little_endian.h"

namespace tessera::media {

std::vector<uint8_t> encodeVideoPacket(const VideoPacket& p) {
  TESSERA_CHECK(!p.payload.empty() && p.payload.size() <= kMaxVideoChunkBytes,
                "media::encodeVideoPacket(): the payload is " + std::to_string(p.payload.size()) +
                    " bytes, expected 1.." + std::to_string(kMaxVideoChunkBytes));
  TESSERA_CHECK(p.chunk < p.chunks && p.chunks <= kMaxVideoChunks,
                "media::encodeVideoPacket(): chunk " + std::to_string(p.chunk) + " of " +
                    std::to_string(p.chunks));
  std::vector<uint8_t> bytes(kVideoHeaderBytes + p.payload.size());
  bytes[0] = kVideoPacketVersion;
  bytes[1] = p.key ? 1 : 0;
  putLe16(&bytes[2], p.site);
  putLe32(&bytes[4], p.frame);
  bytes[8] = p.chunk;
  bytes[9] = p.chunks;
  putLe16(&bytes[10], p.width);
  putLe16(&bytes[12], p.height);
  putLe16(&bytes[14], uint16_t(p.payload.size()));
  std::copy(p.payload.begin(), p.payload.end(), bytes.begin() + kVideoHeaderBytes);
  return bytes;
}

std::optional<std::string> decodeVideoPacket(std::span<const uint8_t> bytes, VideoPacket& out) {
  const auto refuse = [](const std::string& why) { return "video packet: " + why; };
  if (bytes.size() < kVideoHeaderBytes + 1)
    return refuse(std::to_string(bytes.size()) + " bytes, shorter than the header and one byte (" +
                  std::to_string(kVideoHeaderBytes + 1) + ")");
  if (bytes.size() > kMaxVideoPacketBytes)
    return refuse(std::to_string(bytes.size()) + " bytes, more than the largest packet (" +
                  std::to_string(kMaxVideoPacketBytes) + ")");
  if (bytes[0] != kVideoPacketVersion)
    return refuse("version " + std::to_string(bytes[0]) + ", expected " +
                  std::to_string(kVideoPacketVersion));
  if ((bytes[1] & ~1u) != 0)
    return refuse("flags " + std::to_string(bytes[1]) + " set reserved bits (only bit 0 is used)");
  const uint8_t chunk = bytes[8], chunks = bytes[9];
  if (chunks < 1 || chunks > kMaxVideoChunks)
    return refuse("chunk count " + std::to_string(chunks) + ", expected 1.." +
                  std::to_string(kMaxVideoChunks));
  if (chunk >= chunks)
    return refuse("chunk " + std::to_string(chunk) + " of " + std::to_string(chunks));
  const uint16_t width = getLe16(&bytes[10]), height = getLe16(&bytes[12]);
  if (width < 16 || height < 16 || width > kMaxVideoSide || height > kMaxVideoSide)
    return refuse("picture size " + std::to_string(width) + "x" + std::to_string(height) +
                  ", expected 16.." + std::to_string(kMaxVideoSide) + " each way");
  const size_t payload = getLe16(&bytes[14]);
  if (payload != bytes.size() - kVideoHeaderBytes)
    return refuse("payload size " + std::to_string(payload) + " but " +
                  std::to_string(bytes.size() - kVideoHeaderBytes) + " bytes follow the header");
  out.key = (bytes[1] & 1) != 0;
  out.site = getLe16(&bytes[2]);
  out.frame = getLe32(&bytes[4]);
  out.chunk = chunk;
  out.chunks = chunks;
  out.width = width;
  out.height = height;
  out.payload.assign(bytes.begin() + kVideoHeaderBytes, bytes.end());
  return {};
}

void setVideoPacketSite(std::vector<uint8_t>& bytes, uint16_t site) {
  TESSERA_CHECK(bytes.size() >= kVideoHeaderBytes, "media::setVideoPacketSite(): not a packet");
  putLe16(&bytes[2], site);
}

// ---------------------------------------------------------------------------------------------

VideoSender::VideoSender(const VideoSettings& settings, uint16_t site)
    : mEncoder(settings), mSite(site) {}

std::vector<std::vector<uint8_t>> VideoSender::send(const VideoPicture& picture) {
  const EncodedVideo unit = mEncoder.encode(picture);
  std::vector<std::vector<uint8_t>> out;
  if (unit.bytes.empty()) return out;
  const size_t chunks = (unit.bytes.size() + kMaxVideoChunkBytes - 1) / kMaxVideoChunkBytes;
  if (chunks > size_t(kMaxVideoChunks)) {
    // Cannot happen within the VBV cap (1 MB is seconds of any allowed rate); a receiver would
    // refuse it, so it is not sent, and the next picture starts over from a key.
    mEncoder.forceKey();
    ++mFrame;
    return out;
  }
  VideoPacket p;
  p.site = mSite;
  p.frame = mFrame++;
  p.key = unit.key;
  p.chunks = uint8_t(chunks);
  p.width = uint16_t(mEncoder.settings().width);
  p.height = uint16_t(mEncoder.settings().height);
  for (size_t c = 0; c < chunks; ++c) {
    const size_t from = c * kMaxVideoChunkBytes;
    const size_t to = std::min(unit.bytes.size(), from + kMaxVideoChunkBytes);
    p.chunk = uint8_t(c);
    p.payload.assign(unit.bytes.begin() + long(from), unit.bytes.begin() + long(to));
    out.push_back(encodeVideoPacket(p));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

std::optional<VideoAssembler::Unit> VideoAssembler::add(const VideoPacket& p) {
  // Serial number arithmetic (RFC 1982) on the 32-bit frame numbers: "later" is within half
  // the space ahead.
  const auto later = [](uint32_t a, uint32_t b) { return a != b && uint32_t(a - b) < 0x80000000u; };
  if (mStarted && p.frame != mFrame && !later(p.frame, mFrame)) return {};  // an older unit
  if (mStarted && p.frame == mFrame && mParts.empty()) return {};           // completed or given up
  if (!mStarted || p.frame != mFrame) {
    // A later access unit: the one being joined (if any) lost a chunk and is given up; the
    // gap it leaves is counted when the next whole unit completes.
    mStarted = true;
    mFrame = p.frame;
    mChunks = p.chunks;
    mKey = p.key;
    mWidth = p.width;
    mHeight = p.height;
    mParts.assign(p.chunks, {});
    mHave = 0;
  }
  if (p.chunks != mChunks || p.key != mKey || p.width != mWidth || p.height != mHeight) {
    mParts.clear();  // chunks of one access unit that disagree: the unit is given up
    mHave = 0;
    return {};
  }
  if (!mParts[p.chunk].empty()) return {};  // a duplicate
  mParts[p.chunk] = p.payload;
  if (++mHave < mChunks) return {};
  Unit u;
  u.frame = mFrame;
  u.key = mKey;
  u.width = mWidth;
  u.height = mHeight;
  u.after_gap = mHaveWhole && mFrame != mLastWhole + 1;
  if (u.after_gap) mLost += uint32_t(mFrame - mLastWhole - 1);
  for (auto& part : mParts) u.bytes.insert(u.bytes.end(), part.begin(), part.end());
  mParts.clear();
  mHave = 0;
  mHaveWhole = true;
  mLastWhole = mFrame;
  return u;
}

// ---------------------------------------------------------------------------------------------

void VideoReceiver::setShown(bool shown) {
  if (shown == mShown) return;
  mShown = shown;
  if (!shown) mNeedKey = true;  // what it skips leaves the decoder's references stale
}

bool VideoReceiver::receive(const VideoPacket& packet) {
  ++mStats.packets;
  mWidth = packet.width;
  mHeight = packet.height;
  std::optional<VideoAssembler::Unit> unit = mAssembler.add(packet);
  mStats.lost = mAssembler.lost();
  if (!unit) return false;
  ++mStats.units;
  if (unit->after_gap) mNeedKey = true;
  if (!mShown || (mNeedKey && !unit->key)) {
    ++mStats.skipped;
    return false;
  }
  if (mNeedKey) mDecoder.reset();
  bool fresh = false;
  if (auto why = mDecoder.decode(unit->bytes, fresh)) {
    ++mStats.errors;
    mStats.last_error = *why;
    mNeedKey = true;  // the references may be broken: the picture waits for the next key
    return false;
  }
  mNeedKey = false;
  if (!fresh) return false;
  ++mStats.decoded;
  ++mGeneration;
  return true;
}

}  // namespace tessera::media
