#include <tessera/render/video_textures.h>

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

namespace tessera::render {

VideoTextures::VideoTextures() = default;
VideoTextures::~VideoTextures() = default;

std::optional<std::string> VideoTextures::receive(std::span<const uint8_t> bytes) {
  ++mStats.packets;
  media::VideoPacket packet;
  if (auto why = media::decodeVideoPacket(bytes, packet)) {
    ++mStats.refused;
    mStats.last_problem = *why;
    return why;
  }
  auto it = mStreams.find(packet.site);
  if (it == mStreams.end()) {
    if (mStreams.size() >= kMaxStreams) {
      ++mStats.refused;
      mStats.last_problem = "video: more than " + std::to_string(kMaxStreams) + " streams";
      return mStats.last_problem;
    }
    it = mStreams.emplace(packet.site, std::make_unique<Stream>()).first;
    it->second->receiver.setShown(mShown.count(packet.site) > 0);
  }
  media::VideoReceiver& r = it->second->receiver;
  const uint64_t errors = r.stats().errors;
  r.receive(packet);
  if (r.stats().errors != errors) mStats.last_problem = r.stats().last_error;
  return {};
}

void VideoTextures::setShown(const std::set<uint32_t>& sources) {
  mShown = sources;
  for (auto& [source, stream] : mStreams) stream->receiver.setShown(sources.count(source) > 0);
}

bool VideoTextures::upload() {
  bool remade = false;
  for (auto& [source, stream] : mStreams) {
    const media::VideoReceiver& r = stream->receiver;
    if (r.generation() == stream->uploaded) continue;
    const media::VideoPicture& p = r.picture();
    if (p.empty()) continue;
    if (!stream->texture || stream->texture.width() != uint32_t(p.width) ||
        stream->texture.height() != uint32_t(p.height)) {
      stream->texture = GlTexture(uint32_t(p.width), uint32_t(p.height), GL_RGBA8);
      remade = true;
    }
    stream->texture.upload(p.rgba.data());
    stream->uploaded = r.generation();
    ++mStats.uploads;
  }
  return remade;
}

const GlTexture* VideoTextures::texture(uint32_t source) const {
  auto it = mStreams.find(source);
  return it != mStreams.end() && it->second->texture ? &it->second->texture : nullptr;
}

VideoTextureStats VideoTextures::stats() const {
  VideoTextureStats s = mStats;
  s.decoded = s.skipped = s.errors = s.lost = 0;
  for (const auto& [source, stream] : mStreams) {
    const media::VideoReceiverStats& r = stream->receiver.stats();
    s.decoded += r.decoded;
    s.skipped += r.skipped;
    s.errors += r.errors;
    s.lost += r.lost;
  }
  return s;
}

}  // namespace tessera::render
