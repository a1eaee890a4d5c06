#include <tessera/media/video_codec.h>

#include <algorithm>
#include <cmath>
#include <mutex>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/imgutils.h>
#include <libavutil/log.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include "ffmpeg_error.h"

namespace tessera::media {

namespace {

struct CodecContextFree {
  void operator()(AVCodecContext* c) const { avcodec_free_context(&c); }
};
struct FrameFree {
  void operator()(AVFrame* f) const { av_frame_free(&f); }
};
struct PacketFree {
  void operator()(AVPacket* p) const { av_packet_free(&p); }
};
struct SwsFree {
  void operator()(SwsContext* s) const { sws_freeContext(s); }
};
using CodecContextPtr = std::unique_ptr<AVCodecContext, CodecContextFree>;
using FramePtr = std::unique_ptr<AVFrame, FrameFree>;
using PacketPtr = std::unique_ptr<AVPacket, PacketFree>;
using SwsPtr = std::unique_ptr<SwsContext, SwsFree>;

/// libavcodec logs every damaged packet it is given to stderr; outside bytes are normal here and
/// the receivers count and report errors themselves, so only fatal messages get through (the
/// one global of this library: FFmpeg's log level).
void quietFfmpeg() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_level(AV_LOG_FATAL); });
}

}  // namespace

int VideoSettings::refreshFrames() const {
  return std::max(2, int(std::lround(refresh_s * fps)));
}

std::optional<std::string> VideoSettings::problem() const {
  auto side = [](int v, const char* name) -> std::optional<std::string> {
    if (v < 16 || v > kMaxVideoSide || v % 2 != 0)
      return std::string("video settings: ") + name + " " + std::to_string(v) +
             " must be even and in 16.." + std::to_string(kMaxVideoSide);
    return {};
  };
  if (auto p = side(width, "width")) return p;
  if (auto p = side(height, "height")) return p;
  if (!(fps > 0.0 && fps <= 120.0))
    return "video settings: fps " + std::to_string(fps) + " must be in (0, 120]";
  if (kbps < 50 || kbps > 50000)
    return "video settings: kbps " + std::to_string(kbps) + " must be in 50..50000";
  if (!(refresh_s > 0.0 && refresh_s <= 10.0))
    return "video settings: refresh_s " + std::to_string(refresh_s) + " must be in (0, 10]";
  if (!(vbv_s > 0.0 && vbv_s <= 5.0))
    return "video settings: vbv_s " + std::to_string(vbv_s) + " must be in (0, 5]";
  if (threads < 1 || threads > 16)
    return "video settings: threads " + std::to_string(threads) + " must be in 1..16";
  return {};
}

// ---------------------------------------------------------------------------------------------

struct VideoEncoder::Impl {
  CodecContextPtr context;
  FramePtr frame;
  PacketPtr packet;
  SwsPtr sws;
  int sws_w = 0, sws_h = 0;
  int64_t pts = 0;
};

VideoEncoder::VideoEncoder(const VideoSettings& s) : mSettings(s), m(std::make_unique<Impl>()) {
  if (auto p = s.problem()) throw VideoError("media::VideoEncoder: " + *p);
  quietFfmpeg();
  const AVCodec* codec = avcodec_find_encoder_by_name("libx264");
  if (!codec)
    throw VideoError(
        "media::VideoEncoder: this libavcodec has no libx264 encoder (Debian's libavcodec59 "
        "has it; a build without GPL parts does not)");
  m->context.reset(avcodec_alloc_context3(codec));
  if (!m->context) throw VideoError("media::VideoEncoder: out of memory");
  AVCodecContext* c = m->context.get();
  c->width = s.width;
  c->height = s.height;
  c->pix_fmt = AV_PIX_FMT_YUV420P;
  // A millisecond time base: pts are frame numbers scaled, so the rate control sees the real
  // frame rate; framerate tells x264 the same.
  c->time_base = AVRational{1, 1000};
  c->framerate = av_d2q(s.fps, 1000);
  c->bit_rate = int64_t(s.kbps) * 1000;
  c->rc_max_rate = c->bit_rate;
  c->rc_min_rate = 0;
  c->rc_buffer_size = int(std::max(1.0, double(c->bit_rate) * s.vbv_s));
  c->gop_size = s.refreshFrames();
  c->max_b_frames = 0;
  c->thread_count = s.threads;
  c->flags |= AV_CODEC_FLAG_LOW_DELAY;
  auto set = [&](const char* key, const char* value) {
    const int r = av_opt_set(c->priv_data, key, value, 0);
    if (r < 0)
      throw VideoError(std::string("media::VideoEncoder: libx264 option ") + key + "=" + value +
                       ": " + avError(r));
  };
  set("preset", s.preset.c_str());
  set("tune", "zerolatency");
  if (s.intra_refresh) set("intra-refresh", "1");
  // Headers (SPS/PPS) in the stream at every key, not out of band: a receiver may start at any.
  set("x264-params", "repeat-headers=1");
  if (const int r = avcodec_open2(c, codec, nullptr); r < 0)
    throw VideoError("media::VideoEncoder: avcodec_open2(libx264, " + std::to_string(s.width) +
                     "x" + std::to_string(s.height) + ", preset " + s.preset + "): " + avError(r));
  m->frame.reset(av_frame_alloc());
  m->packet.reset(av_packet_alloc());
  if (!m->frame || !m->packet) throw VideoError("media::VideoEncoder: out of memory");
  m->frame->format = AV_PIX_FMT_YUV420P;
  m->frame->width = s.width;
  m->frame->height = s.height;
  if (const int r = av_frame_get_buffer(m->frame.get(), 0); r < 0)
    throw VideoError("media::VideoEncoder: av_frame_get_buffer: " + avError(r));
}

VideoEncoder::~VideoEncoder() = default;
VideoEncoder::VideoEncoder(VideoEncoder&&) noexcept = default;
VideoEncoder& VideoEncoder::operator=(VideoEncoder&&) noexcept = default;

EncodedVideo VideoEncoder::encode(const VideoPicture& picture) {
  if (picture.empty() || picture.width > kMaxVideoSide || picture.height > kMaxVideoSide ||
      picture.rgba.size() != size_t(picture.width) * size_t(picture.height) * 4)
    throw VideoError("media::VideoEncoder::encode(): a picture of " +
                     std::to_string(picture.width) + "x" + std::to_string(picture.height) +
                     " with " + std::to_string(picture.rgba.size()) + " bytes");
  AVCodecContext* c = m->context.get();
  if (!m->sws || m->sws_w != picture.width || m->sws_h != picture.height) {
    m->sws.reset(sws_getContext(picture.width, picture.height, AV_PIX_FMT_RGBA, c->width, c->height,
                                AV_PIX_FMT_YUV420P, SWS_BILINEAR, nullptr, nullptr, nullptr));
    if (!m->sws) throw VideoError("media::VideoEncoder::encode(): sws_getContext failed");
    m->sws_w = picture.width;
    m->sws_h = picture.height;
  }
  if (const int r = av_frame_make_writable(m->frame.get()); r < 0)
    throw VideoError("media::VideoEncoder::encode(): av_frame_make_writable: " + avError(r));
  const uint8_t* src[1] = {picture.rgba.data()};
  const int stride[1] = {picture.width * 4};
  sws_scale(m->sws.get(), src, stride, 0, picture.height, m->frame->data, m->frame->linesize);
  m->frame->pts = int64_t(std::llround(double(m->pts++) * 1000.0 / mSettings.fps));
  m->frame->pict_type = mForceKey ? AV_PICTURE_TYPE_I : AV_PICTURE_TYPE_NONE;
  m->frame->key_frame = mForceKey ? 1 : 0;
  mForceKey = false;
  if (const int r = avcodec_send_frame(c, m->frame.get()); r < 0)
    throw VideoError("media::VideoEncoder::encode(): avcodec_send_frame: " + avError(r));
  EncodedVideo out;
  while (true) {
    const int r = avcodec_receive_packet(c, m->packet.get());
    if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) break;
    if (r < 0)
      throw VideoError("media::VideoEncoder::encode(): avcodec_receive_packet: " + avError(r));
    out.bytes.insert(out.bytes.end(), m->packet->data, m->packet->data + m->packet->size);
    out.key |= (m->packet->flags & AV_PKT_FLAG_KEY) != 0;
    av_packet_unref(m->packet.get());
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

struct VideoDecoder::Impl {
  CodecContextPtr context;
  FramePtr frame;
  PacketPtr packet;
  SwsPtr sws;
  int sws_w = 0, sws_h = 0, sws_format = -1;
  std::vector<uint8_t> padded;  // the access unit with AV_INPUT_BUFFER_PADDING_SIZE zeros

  void open() {
    quietFfmpeg();
    const AVCodec* codec = avcodec_find_decoder(AV_CODEC_ID_H264);
    if (!codec) throw VideoError("media::VideoDecoder: this libavcodec has no H.264 decoder");
    context.reset(avcodec_alloc_context3(codec));
    if (!context) throw VideoError("media::VideoDecoder: out of memory");
    // One thread: frame threads would hold pictures back (a frame of delay per thread).
    context->thread_count = 1;
    context->flags |= AV_CODEC_FLAG_LOW_DELAY;
    // Bounds on what outside bytes can make the decoder allocate.
    context->max_pixels = int64_t(kMaxVideoSide) * kMaxVideoSide;
    if (const int r = avcodec_open2(context.get(), codec, nullptr); r < 0)
      throw VideoError("media::VideoDecoder: avcodec_open2(h264): " + avError(r));
  }
};

VideoDecoder::VideoDecoder() : m(std::make_unique<Impl>()) {
  m->open();
  m->frame.reset(av_frame_alloc());
  m->packet.reset(av_packet_alloc());
  if (!m->frame || !m->packet) throw VideoError("media::VideoDecoder: out of memory");
}

VideoDecoder::~VideoDecoder() = default;
VideoDecoder::VideoDecoder(VideoDecoder&&) noexcept = default;
VideoDecoder& VideoDecoder::operator=(VideoDecoder&&) noexcept = default;

void VideoDecoder::reset() {
  avcodec_flush_buffers(m->context.get());
}

std::optional<std::string> VideoDecoder::decode(std::span<const uint8_t> au, bool& fresh) {
  fresh = false;
  if (au.empty()) return std::string("video decoder: an empty access unit");
  if (au.size() > size_t(64) << 20) return std::string("video decoder: an access unit over 64 MiB");
  m->padded.assign(au.begin(), au.end());
  m->padded.resize(au.size() + AV_INPUT_BUFFER_PADDING_SIZE, 0);
  av_packet_unref(m->packet.get());
  m->packet->data = m->padded.data();
  m->packet->size = int(au.size());
  AVCodecContext* c = m->context.get();
  if (const int r = avcodec_send_packet(c, m->packet.get()); r < 0) {
    // The decoder may hold a picture it could not give yet; drain it below regardless.
    std::string why = "video decoder: " + avError(r);
    while (avcodec_receive_frame(c, m->frame.get()) >= 0) av_frame_unref(m->frame.get());
    return why;
  }
  std::optional<std::string> problem;
  while (true) {
    const int r = avcodec_receive_frame(c, m->frame.get());
    if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) break;
    if (r < 0) {
      problem = "video decoder: " + avError(r);
      break;
    }
    AVFrame* f = m->frame.get();
    if ((f->flags & AV_FRAME_FLAG_CORRUPT) || f->decode_error_flags != 0) {
      problem = std::string("video decoder: a corrupt picture (concealed errors): not shown");
      av_frame_unref(f);
      continue;
    }
    if (f->width < 16 || f->height < 16 || f->width > kMaxVideoSide || f->height > kMaxVideoSide) {
      problem = "video decoder: a picture of " + std::to_string(f->width) + "x" +
                std::to_string(f->height) + " (16.." + std::to_string(kMaxVideoSide) + " each way)";
      av_frame_unref(f);
      continue;
    }
    if (!m->sws || m->sws_w != f->width || m->sws_h != f->height || m->sws_format != f->format) {
      m->sws.reset(sws_getContext(f->width, f->height, AVPixelFormat(f->format), f->width,
                                  f->height, AV_PIX_FMT_RGBA, SWS_BILINEAR, nullptr, nullptr,
                                  nullptr));
      m->sws_w = f->width;
      m->sws_h = f->height;
      m->sws_format = f->format;
      if (!m->sws) {
        av_frame_unref(f);
        return "video decoder: no conversion from pixel format " + std::to_string(f->format);
      }
    }
    if (mPicture.width != f->width || mPicture.height != f->height)
      mPicture.resize(f->width, f->height);
    uint8_t* dst[1] = {mPicture.rgba.data()};
    const int stride[1] = {f->width * 4};
    sws_scale(m->sws.get(), f->data, f->linesize, 0, f->height, dst, stride);
    av_frame_unref(f);
    fresh = true;
  }
  return problem;
}

double videoPsnr(const VideoPicture& a, const VideoPicture& b, int x, int y, int w, int h) {
  double sum = 0;
  size_t n = 0;
  for (int yy = y; yy < y + h; ++yy)
    for (int xx = x; xx < x + w; ++xx) {
      const uint8_t* p = a.pixel(xx, yy);
      const uint8_t* q = b.pixel(xx, yy);
      for (int k = 0; k < 3; ++k) {
        const double d = double(p[k]) - double(q[k]);
        sum += d * d;
        ++n;
      }
    }
  if (n == 0 || sum == 0) return 99.0;
  return 10.0 * std::log10(255.0 * 255.0 / (sum / double(n)));
}

}  // namespace tessera::media
