// Voice and video of a site session: the microphone and speaker clocked from the welcome, the
// video source paced by the loop, the counts said at the end.
#include "site_session_impl.h"

namespace tessera::collab {

void SiteSession::Impl::pumpVideo() {
  if (!video_sender) return;
  const auto now = Clock::now();
  if (now < video_next) return;
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(1.0 / video_sender->encoder().settings().fps));
  video_next += period;
  if (video_next < now) video_next = now + period;  // late: skip, no burst
  if (!video_source->grab(video_picture)) return;   // a camera without a new picture
  const auto start = Clock::now();
  const auto packets = video_sender->send(video_picture);
  video_encode_ms += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  ++video_frames;
  site::ToMaster m;
  for (const auto& p : packets) {
    video_bytes += p.size();
    m.set_video(p.data(), p.size());
    client->send(m);
  }
}

void SiteSession::Impl::sleepSendingVideo(Clock::time_point until) {
  while (video_sender && video_next < until) {
    std::this_thread::sleep_until(video_next);
    pumpVideo();
  }
  std::this_thread::sleep_until(until);
}

void SiteSession::Impl::sayVideo() {
  if (!video_sender || video_frames == 0) return;
  const double s = std::max(1e-3, elapsed());
  char line[200];
  std::snprintf(line, sizeof line,
                "video: sent %llu pictures, %llu bytes (%.0f kbit/s), %.2f ms to encode each",
                (unsigned long long)video_frames, (unsigned long long)video_bytes,
                double(video_bytes) * 8.0 / 1000.0 / s, video_encode_ms / double(video_frames));
  say(line);
}

double SiteSession::Impl::voiceNow() const {
  return std::chrono::duration<double>(Clock::now() - voice_start).count();
}

void SiteSession::Impl::tickVoice() {
  if (!station) return;
  const double now = voiceNow();
  const auto send = [this](std::vector<uint8_t> bytes) {
    site::ToMaster m;
    m.set_voice(bytes.data(), bytes.size());
    client->send(m);
  };
  if (microphone)
    microphone->pump(now, [&](std::span<const float> frame) { station->sendLive(frame, send); });
  station->advance(now, send);
  if (speaker)
    speaker->pump(now, [this](double at, std::span<float> out) { station->playLive(at, out); });
}

void SiteSession::Impl::writeSpeaker() {
  if (!station || opt.audio_out.empty() || speaker) return;
  try {
    media::writeWav(opt.audio_out, station->speaker());
    say("wrote what this site heard to " + opt.audio_out);
  } catch (const media::WavError& e) {
    std::fprintf(stderr, "tessera-site: %s\n", e.what());
  }
}

}  // namespace tessera::collab
