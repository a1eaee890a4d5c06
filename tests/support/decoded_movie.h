// A movie file read back with libavformat and libavcodec, independently of the writer
// (media/movie_writer.h): its size, duration, frame rate, codec and every frame as RGBA; and the
// PSNR that movie tests compare decoded frames with. Header-only; link libavformat, libavcodec,
// libswscale and libavutil.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libswscale/swscale.h>
}

#include <tessera/render/image.h>

namespace tessera::test {

/// What a movie file holds, decoded independently of the writer.
struct DecodedMovie {
  int width = 0, height = 0;
  double duration_s = 0.0;  ///< the stream's duration
  double fps = 0.0;         ///< its average frame rate
  std::string codec;
  std::vector<render::Image> frames;  ///< RGBA
};

inline DecodedMovie decodeMovie(const std::string& path) {
  DecodedMovie m;
  AVFormatContext* fmt = nullptr;
  EXPECT_EQ(avformat_open_input(&fmt, path.c_str(), nullptr, nullptr), 0) << path;
  if (!fmt) return m;
  EXPECT_GE(avformat_find_stream_info(fmt, nullptr), 0);
  const int si = av_find_best_stream(fmt, AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
  EXPECT_GE(si, 0);
  if (si < 0) {
    avformat_close_input(&fmt);
    return m;
  }
  AVStream* st = fmt->streams[si];
  m.duration_s = double(st->duration) * av_q2d(st->time_base);
  m.fps = av_q2d(st->avg_frame_rate);
  const AVCodec* dec = avcodec_find_decoder(st->codecpar->codec_id);
  m.codec = dec ? dec->name : "?";
  AVCodecContext* c = avcodec_alloc_context3(dec);
  avcodec_parameters_to_context(c, st->codecpar);
  EXPECT_EQ(avcodec_open2(c, dec, nullptr), 0);
  m.width = c->width;
  m.height = c->height;
  AVPacket* pkt = av_packet_alloc();
  AVFrame* f = av_frame_alloc();
  SwsContext* sws = nullptr;
  auto drain = [&] {
    while (avcodec_receive_frame(c, f) == 0) {
      sws =
          sws_getCachedContext(sws, f->width, f->height, AVPixelFormat(f->format), f->width,
                               f->height, AV_PIX_FMT_RGBA, SWS_BICUBIC, nullptr, nullptr, nullptr);
      render::Image img;
      img.width = uint32_t(f->width);
      img.height = uint32_t(f->height);
      img.rgba.resize(size_t(img.width) * img.height * 4);
      uint8_t* dst[1] = {img.rgba.data()};
      const int stride[1] = {int(img.width) * 4};
      sws_scale(sws, f->data, f->linesize, 0, f->height, dst, stride);
      m.frames.push_back(std::move(img));
    }
  };
  while (av_read_frame(fmt, pkt) >= 0) {
    if (pkt->stream_index == si) {
      avcodec_send_packet(c, pkt);
      drain();
    }
    av_packet_unref(pkt);
  }
  avcodec_send_packet(c, nullptr);
  drain();
  sws_freeContext(sws);
  av_frame_free(&f);
  av_packet_free(&pkt);
  avcodec_free_context(&c);
  avformat_close_input(&fmt);
  return m;
}

/// Peak signal-to-noise ratio of the colour channels, dB.
inline double psnr(const render::Image& a, const render::Image& b) {
  double se = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4)
    for (int c = 0; c < 3; ++c, ++n) {
      const double d = double(a.rgba[i + c]) - double(b.rgba[i + c]);
      se += d * d;
    }
  const double mse = se / double(n);
  return mse == 0.0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

}  // namespace tessera::test
