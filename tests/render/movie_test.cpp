// Movies of camera paths (path_frames.h, media/movie_writer.h) read back with libavformat and
// libavcodec: frame count, size and duration, and each decoded frame against the settled render
// of its camera.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libswscale/swscale.h>
}

#include <tessera/media/movie_writer.h>
#include <tessera/render/path_frames.h>
#include <tessera/render/view_renderer.h>

#include "../support/bunny_store_test.h"
#include "../support/bunny_views.h"
#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

/// What a movie file holds, decoded independently of the writer.
struct DecodedMovie {
  int width = 0, height = 0;
  double duration_s = 0.0;  ///< the stream's duration
  double fps = 0.0;         ///< its average frame rate
  std::string codec;
  std::vector<Image> frames;  ///< RGBA
};

DecodedMovie decodeMovie(const std::string& path) {
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
      Image img;
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
double psnr(const Image& a, const Image& b) {
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

class MovieTest : public test::BunnyStoreTest {};

// 12 frames at 8 fps (a path of 1.375 s): the file says 12 frames of 160x120 over 1.5 s, and
// every decoded frame is its camera's settled render within the codec's loss.
TEST_F(MovieTest, AMovieOfAPathHasItsFramesSizeAndDurationAndShowsTheRenders) {
  auto s = lod::PointStore::open(*sDir / "b.tlod");
  ModelInstance inst{s.get(), storeModel(*s)};
  const config::Camera start = test::frontCamera(*s, 0.3);
  config::Camera end = start;
  end.mutable_eye()->set_x(start.eye().x() + 0.2);
  end.mutable_eye()->set_z(start.eye().z() - 0.05);
  config::CameraPath path;
  auto fill = [](config::CameraKeyframe* k, const config::Camera& c, double t) {
    k->set_time(t);
    *k->mutable_eye() = c.eye();
    *k->mutable_target() = c.target();
    *k->mutable_up() = c.up();
  };
  fill(path.add_keyframes(), start, 0.0);
  fill(path.add_keyframes(), end, 1.375);
  const double fps = 8.0;
  ASSERT_EQ(pathFrameCount(path, fps), 12u);

  test::TempDir dir;
  const std::string file = (dir.path() / "path.mp4").string();
  const uint32_t w = 160, h = 120;
  RenderOptions o;
  o.edl.strength = 1.0f;
  std::vector<Image> renders;
  {
    media::MovieSettings ms;
    ms.width = int(w);
    ms.height = int(h);
    ms.fps = fps;
    media::MovieWriter writer(file, ms);
    auto streamer = std::make_shared<ChunkStreamer>();
    forEachPathFrame(path, fps, [&](size_t, double, const config::Camera& c) {
      ViewRenderer r(w, h, streamer);
      renders.push_back(r.renderSettled({&inst, 1}, test::perspectiveView(c, w, h), o));
      writer.write(renders.back().rgba, int(w), int(h));
    });
    EXPECT_FALSE(std::filesystem::exists(file)) << "the movie appears when finished";
    writer.finish();
    EXPECT_EQ(writer.frames(), 12);
    std::printf("encoder: %s\n", writer.encoder().c_str());
  }
  const DecodedMovie m = decodeMovie(file);
  EXPECT_EQ(m.width, int(w));
  EXPECT_EQ(m.height, int(h));
  EXPECT_NEAR(m.fps, fps, 1e-6);
  EXPECT_NEAR(m.duration_s, 12 / fps, 0.5 / fps);
  ASSERT_EQ(m.frames.size(), 12u);
  // The frames move: the first and last renders differ, so matching each to its own is a test.
  EXPECT_LT(psnr(renders.front(), renders.back()), 25.0);
  for (size_t i = 0; i < m.frames.size(); ++i) {
    const double p = psnr(m.frames[i], renders[i]);
    std::printf("frame %zu: PSNR %.1f dB against its render\n", i, p);
    EXPECT_GE(p, 30.0) << "frame " << i;
  }
  std::printf("%s, %dx%d, %.3f s at %.1f fps\n", m.codec.c_str(), m.width, m.height, m.duration_s,
              m.fps);
}

TEST(MovieWriterTest, BadSettingsAndUnwritableOutputsAreRefusedWithAMessage) {
  test::TempDir dir;
  auto refused = [](const std::string& path, const media::MovieSettings& s) -> std::string {
    try {
      media::MovieWriter w(path, s);
    } catch (const media::VideoError& e) {
      return e.what();
    }
    return "";
  };
  media::MovieSettings odd;
  odd.width = 161;
  EXPECT_NE(refused((dir.path() / "a.mp4").string(), odd).find("width 161"), std::string::npos);
  media::MovieSettings nan_fps;
  nan_fps.fps = std::nan("");
  EXPECT_NE(refused((dir.path() / "a.mp4").string(), nan_fps).find("fps"), std::string::npos);
  const std::string missing = (dir.path() / "no-such-folder" / "a.mp4").string();
  const std::string why = refused(missing, media::MovieSettings{});
  EXPECT_NE(why.find("cannot create " + missing), std::string::npos) << why;
  // A writer given a picture of another size says so, and a writer never finished leaves no
  // file behind.
  const std::string unfinished = (dir.path() / "b.mp4").string();
  {
    media::MovieSettings s;
    s.width = 64;
    s.height = 48;
    media::MovieWriter w(unfinished, s);
    std::vector<uint8_t> small(32 * 32 * 4, 0);
    EXPECT_THROW(w.write(small, 32, 32), media::VideoError);
  }
  EXPECT_FALSE(std::filesystem::exists(unfinished));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 0);
}

// A bad path file is refused by the path reader with the file and field named, before a frame.
TEST(PathFramesTest, FrameCountsAndABadPathFile) {
  config::CameraPath one;
  auto* k = one.add_keyframes();
  k->set_time(0.0);
  EXPECT_EQ(pathFrameCount(one, 30.0), 1u);
  config::CameraPath day = one;
  day.add_keyframes()->set_time(86400.0);
  EXPECT_THROW(pathFrameCount(day, 240.0), RenderError);
  EXPECT_EQ(framePngPath("out", 42).string(), "out/frame-000042.png");
  test::TempDir dir;
  const auto bad = dir.path() / "bad.json";
  std::ofstream(bad) << R"({"keyframes": [{"time": 1.0}, {"time": 0.5}]})";
  try {
    sync::loadCameraPath(bad);
    ADD_FAILURE() << "accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace tessera::render
