#include <tessera/media/movie_writer.h>

#include <cmath>
#include <filesystem>
#include <random>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/log.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include "ffmpeg_error.h"

namespace tessera::media {

namespace {

/// The encoders tried, best first: by name, then by codec id.
const AVCodec* findMovieEncoder() {
  if (const AVCodec* c = avcodec_find_encoder_by_name("libx264")) return c;
  for (AVCodecID id : {AV_CODEC_ID_H264, AV_CODEC_ID_HEVC, AV_CODEC_ID_MPEG4}) {
    if (const AVCodec* c = avcodec_find_encoder(id)) return c;
  }
  return nullptr;
}

}  // namespace

std::optional<std::string> MovieSettings::problem() const {
  auto side = [](int v, const char* name) -> std::optional<std::string> {
    if (v < 16 || v > kMaxMovieSide || v % 2 != 0)
      return std::string("movie settings: ") + name + " " + std::to_string(v) +
             " must be even and in 16.." + std::to_string(kMaxMovieSide);
    return {};
  };
  if (auto p = side(width, "width")) return p;
  if (auto p = side(height, "height")) return p;
  if (!(fps > 0.0 && fps <= 240.0))
    return "movie settings: fps " + std::to_string(fps) + " must be in (0, 240]";
  if (crf < 0 || crf > 51)
    return "movie settings: crf " + std::to_string(crf) + " must be in 0..51";
  return {};
}

std::string movieEncoderName() {
  const AVCodec* c = findMovieEncoder();
  return c ? c->name : "";
}

struct MovieWriter::Impl {
  AVFormatContext* format = nullptr;
  AVCodecContext* codec = nullptr;
  AVStream* stream = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  SwsContext* sws = nullptr;
  int64_t pts = 0;

  ~Impl() {
    sws_freeContext(sws);
    av_packet_free(&packet);
    av_frame_free(&frame);
    avcodec_free_context(&codec);
    if (format) {
      if (format->pb) avio_closep(&format->pb);
      avformat_free_context(format);
    }
  }

  /// Sends `f` (nullptr: the end) and writes every packet the encoder has ready.
  void send(AVFrame* f, const std::string& path) {
    if (const int r = avcodec_send_frame(codec, f); r < 0)
      throw VideoError("media::MovieWriter: " + path + ": encoding: " + avError(r));
    while (true) {
      const int r = avcodec_receive_packet(codec, packet);
      if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return;
      if (r < 0) throw VideoError("media::MovieWriter: " + path + ": encoding: " + avError(r));
      if (packet->duration == 0) packet->duration = 1;
      av_packet_rescale_ts(packet, codec->time_base, stream->time_base);
      packet->stream_index = stream->index;
      if (const int w = av_interleaved_write_frame(format, packet); w < 0)
        throw VideoError("media::MovieWriter: writing " + path + ": " + avError(w));
    }
  }
};

MovieWriter::MovieWriter(const std::string& path, const MovieSettings& s)
    : m(std::make_unique<Impl>()), mPath(path) {
  if (auto p = s.problem()) throw VideoError("media::MovieWriter: " + path + ": " + *p);
  const AVCodec* encoder = findMovieEncoder();
  if (!encoder)
    throw VideoError("media::MovieWriter: this libavcodec has no H.264, HEVC or MPEG-4 encoder");
  mEncoder = encoder->name;
  // Encoders log their statistics to stderr; errors come back in this writer's messages.
  if (av_log_get_level() > AV_LOG_ERROR) av_log_set_level(AV_LOG_ERROR);
  const std::filesystem::path p(path);
  mTemp = (p.parent_path() /
           ("." + p.filename().string() + ".part-" + std::to_string(std::random_device{}())))
              .string();
  if (const int r = avformat_alloc_output_context2(&m->format, nullptr, "mp4", mTemp.c_str());
      r < 0 || !m->format)
    throw VideoError("media::MovieWriter: " + path + ": the MP4 muxer: " + avError(r));
  m->codec = avcodec_alloc_context3(encoder);
  m->frame = av_frame_alloc();
  m->packet = av_packet_alloc();
  if (!m->codec || !m->frame || !m->packet) throw VideoError("media::MovieWriter: out of memory");
  AVCodecContext* c = m->codec;
  c->width = s.width;
  c->height = s.height;
  c->pix_fmt = AV_PIX_FMT_YUV420P;
  c->framerate = av_d2q(s.fps, 100000);
  c->time_base = av_inv_q(c->framerate);
  c->gop_size = std::max(1, int(std::lround(2.0 * s.fps)));  // a key frame every 2 s
  if (m->format->oformat->flags & AVFMT_GLOBALHEADER) c->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  if (mEncoder == "libx264") {
    av_opt_set(c->priv_data, "preset", "medium", 0);
    av_opt_set(c->priv_data, "crf", std::to_string(s.crf).c_str(), 0);
  } else {
    c->bit_rate = int64_t(0.2 * s.width * s.height * s.fps);
  }
  if (const int r = avcodec_open2(c, encoder, nullptr); r < 0)
    throw VideoError("media::MovieWriter: " + path + ": opening " + mEncoder + " for " +
                     std::to_string(s.width) + "x" + std::to_string(s.height) + ": " + avError(r));
  m->stream = avformat_new_stream(m->format, nullptr);
  if (!m->stream) throw VideoError("media::MovieWriter: out of memory");
  m->stream->time_base = c->time_base;
  m->stream->avg_frame_rate = c->framerate;
  if (const int r = avcodec_parameters_from_context(m->stream->codecpar, c); r < 0)
    throw VideoError("media::MovieWriter: " + path + ": " + avError(r));
  if (const int r = avio_open(&m->format->pb, mTemp.c_str(), AVIO_FLAG_WRITE); r < 0)
    throw VideoError("media::MovieWriter: cannot create " + path + ": " + avError(r));
  if (const int r = avformat_write_header(m->format, nullptr); r < 0) {
    std::error_code ec;
    std::filesystem::remove(mTemp, ec);
    throw VideoError("media::MovieWriter: writing " + path + ": " + avError(r));
  }
  m->frame->format = AV_PIX_FMT_YUV420P;
  m->frame->width = s.width;
  m->frame->height = s.height;
  if (const int r = av_frame_get_buffer(m->frame, 0); r < 0)
    throw VideoError("media::MovieWriter: " + avError(r));
  m->sws = sws_getContext(s.width, s.height, AV_PIX_FMT_RGBA, s.width, s.height, AV_PIX_FMT_YUV420P,
                          SWS_BICUBIC, nullptr, nullptr, nullptr);
  if (!m->sws) throw VideoError("media::MovieWriter: sws_getContext failed");
}

MovieWriter::~MovieWriter() {
  if (!mDone) {
    m.reset();  // closes the file first
    std::error_code ec;
    std::filesystem::remove(mTemp, ec);
  }
}

void MovieWriter::write(std::span<const uint8_t> rgba, int width, int height) {
  AVCodecContext* c = m->codec;
  if (mDone || width != c->width || height != c->height ||
      rgba.size() != size_t(width) * size_t(height) * 4)
    throw VideoError("media::MovieWriter: " + mPath + ": frame " + std::to_string(mFrames) +
                     " is " + std::to_string(width) + "x" + std::to_string(height) +
                     ", the movie " + std::to_string(c->width) + "x" + std::to_string(c->height));
  if (const int r = av_frame_make_writable(m->frame); r < 0)
    throw VideoError("media::MovieWriter: " + avError(r));
  const uint8_t* src[1] = {rgba.data()};
  const int stride[1] = {width * 4};
  sws_scale(m->sws, src, stride, 0, height, m->frame->data, m->frame->linesize);
  m->frame->pts = m->pts++;
  m->send(m->frame, mPath);
  ++mFrames;
}

void MovieWriter::finish() {
  if (mDone) return;
  m->send(nullptr, mPath);
  if (const int r = av_write_trailer(m->format); r < 0)
    throw VideoError("media::MovieWriter: writing " + mPath + ": " + avError(r));
  if (const int r = avio_closep(&m->format->pb); r < 0)
    throw VideoError("media::MovieWriter: closing " + mPath + ": " + avError(r));
  std::error_code ec;
  std::filesystem::rename(mTemp, mPath, ec);
  if (ec) throw VideoError("media::MovieWriter: " + mPath + ": " + ec.message());
  mDone = true;
}

}  // namespace tessera::media
