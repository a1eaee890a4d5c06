// Movies of camera paths (path_frames.h, media/movie_writer.h) read back with libavformat and
// libavcodec: frame count, size and duration, and each decoded frame against the settled render
// of its camera; the box filter that scales a movie's frames (image.h, resizeImage()).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include <tessera/core/check.h>
#include <tessera/media/movie_writer.h>
#include <tessera/render/path_frames.h>
#include <tessera/render/view_renderer.h>

#include "../support/bunny_store_test.h"
#include "../support/bunny_views.h"
#include "../support/decoded_movie.h"
#include "../support/temp_dir.h"

namespace tessera::render {
namespace {

using test::DecodedMovie;
using test::decodeMovie;
using test::psnr;

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

namespace tessera::render {
namespace {

// The box filter that scales a wall's picture to a movie's --size: each new pixel is the mean
// of the old ones under it weighted by the area they share, worked out here by hand.
TEST(ResizeImageTest, EachPixelIsTheAreaWeightedMeanOfThePixelsUnderIt) {
  Image img;
  img.width = 3;
  img.height = 1;
  img.rgba = {0, 30, 90, 255, 60, 90, 150, 255, 120, 150, 210, 255};
  // 3 pixels to 2: [0, 1.5) and [1.5, 3), each old pixel's share 1 / 1.5 or 0.5 / 1.5.
  const Image two = resizeImage(img, 2, 1);
  ASSERT_EQ(two.rgba.size(), 8u);
  EXPECT_EQ(two.rgba[0], 20);  // (0 * 1 + 60 * 0.5) / 1.5
  EXPECT_EQ(two.rgba[1], 50);  // (30 + 45) / 1.5
  EXPECT_EQ(two.rgba[4], 100);  // (30 + 120) / 1.5
  EXPECT_EQ(two.rgba[6], 190);  // (75 + 210) / 1.5
  EXPECT_EQ(two.rgba[3], 255);
  // Up: 3x1 to 6x2 copies each pixel to two columns and both rows.
  const Image up = resizeImage(img, 6, 2);
  for (uint32_t y = 0; y < 2; ++y)
    for (uint32_t x = 0; x < 6; ++x)
      for (int c = 0; c < 4; ++c)
        EXPECT_EQ(up.rgba[(size_t(y) * 6 + x) * 4 + c], img.rgba[(x / 2) * 4 + c]) << x << "," << y;
  // The same size changes nothing; a bad size is a caller's bug.
  EXPECT_EQ(resizeImage(img, 3, 1).rgba, img.rgba);
  EXPECT_THROW(resizeImage(img, 0, 1), PreconditionError);
}

}  // namespace
}  // namespace tessera::render
