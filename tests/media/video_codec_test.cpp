// Video insets: the real H.264 path without sockets: libx264 in, FFmpeg's decoder out,
// through the packets and the receiver; the test pattern read back from what comes out; late
// joiners, lost, corrupt, truncated and oversized packets.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include <unistd.h>

#include <tessera/media/video_packet.h>
#include <tessera/media/video_pattern.h>
#include <tessera/media/video_source.h>

namespace {

using namespace tessera::media;

/// `frames` pattern pictures (640x480 unless given), their packets per access unit.
std::vector<std::vector<std::vector<uint8_t>>> stream(int frames, VideoSettings s = {}) {
  VideoSender sender(s, 3);
  std::vector<std::vector<std::vector<uint8_t>>> out;
  VideoPicture p;
  for (int f = 0; f < frames; ++f) {
    drawTestPattern(p, s.width, s.height, {uint32_t(f), 1000u + uint32_t(f) * 33u});
    out.push_back(sender.send(p));
  }
  return out;
}

VideoPacket parse(const std::vector<uint8_t>& bytes) {
  VideoPacket p;
  EXPECT_EQ(decodeVideoPacket(bytes, p), std::nullopt);
  return p;
}

/// The frame number the receiver's picture shows (-1: none or unreadable).
int shownFrame(const VideoReceiver& r) {
  const VideoPicture& p = r.picture();
  if (p.empty()) return -1;
  const auto code = readTestPattern(p.rgba.data(), p.width, 0, 0, p.width, p.height);
  return code ? int(code->frame) : -1;
}

TEST(VideoPattern, ReadsBackItsCodeScaledAndRefusesBlankPictures) {
  VideoPicture p;
  drawTestPattern(p, 640, 480, {123456, 0xDEADBEEF});
  auto code = readTestPattern(p.rgba.data(), 640, 0, 0, 640, 480);
  ASSERT_TRUE(code);
  EXPECT_EQ(code->frame, 123456u);
  EXPECT_EQ(code->time_ms, 0xDEADBEEFu);
  // A quarter size, nearest-neighbour scaled into a larger image at an offset.
  std::vector<uint8_t> image(400 * 300 * 4, 0);
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x)
      std::copy_n(p.pixel(x * 4, y * 4), 4, &image[(size_t(y + 50) * 400 + x + 30) * 4]);
  code = readTestPattern(image.data(), 400, 30, 50, 160, 120);
  ASSERT_TRUE(code);
  EXPECT_EQ(code->frame, 123456u);
  // All black, all white: no code.
  EXPECT_FALSE(readTestPattern(image.data(), 400, 250, 0, 100, 40));
  std::vector<uint8_t> white(64 * 64 * 4, 255);
  EXPECT_FALSE(readTestPattern(white.data(), 64, 0, 0, 64, 64));
  // One block flipped: the checksum says so.
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 40; ++x) p.pixel(x, y)[0] = p.pixel(x, y)[1] = p.pixel(x, y)[2] ^= 255;
  EXPECT_FALSE(readTestPattern(p.rgba.data(), 640, 0, 0, 640, 480));
}

TEST(VideoCodec, EncodesAtTheCapAndDecodesEveryFrameWell) {
  VideoSettings s;
  const auto packets = stream(90, s);
  size_t bytes = 0;
  int keys = 0;
  VideoReceiver r;
  for (size_t f = 0; f < packets.size(); ++f) {
    ASSERT_FALSE(packets[f].empty()) << "zerolatency: every picture gives its access unit at once";
    for (const auto& b : packets[f]) {
      bytes += b.size();
      const VideoPacket p = parse(b);
      keys += p.key && p.chunk == 0;
      const bool changed = r.receive(p);
      if (p.chunk + 1 == p.chunks) {
        EXPECT_TRUE(changed) << "frame " << f;
        EXPECT_EQ(shownFrame(r), int(f));
      }
    }
  }
  // 3 s at 1000 kbit/s: within the cap (the VBV lets the first second run a little over).
  const double kbps = double(bytes) * 8.0 / 3.0 / 1000.0;
  std::printf("%.0f kbit/s, %d keys in 90 frames\n", kbps, keys);
  EXPECT_LT(kbps, 1.15 * s.kbps);
  EXPECT_GT(kbps, 0.3 * s.kbps);
  EXPECT_EQ(keys, 90 / s.refreshFrames()) << "a refresh every refresh_s";
  VideoPicture sent;
  drawTestPattern(sent, 640, 480, {89, 1000u + 89u * 33u});
  const double psnr = videoPsnr(sent, r.picture(), 0, 0, 640, 480);
  std::printf("PSNR %.1f dB\n", psnr);
  EXPECT_GT(psnr, 32.0);
  VideoPicture other;  // the test can fail: another frame scores far lower
  drawTestPattern(other, 640, 480, {80, 1000u + 80u * 33u});
  EXPECT_LT(videoPsnr(other, r.picture(), 0, 0, 640, 480), psnr - 10.0);
  EXPECT_EQ(r.stats().errors, 0u);
  EXPECT_EQ(r.stats().lost, 0u);
}

/// Feeds frames [from, to) of `packets` to `r`; returns the first frame whose picture showed.
int feed(VideoReceiver& r, const std::vector<std::vector<std::vector<uint8_t>>>& packets, int from,
         int to) {
  int first = -1;
  for (int f = from; f < to; ++f)
    for (const auto& b : packets[size_t(f)])
      if (r.receive(parse(b)) && first < 0) first = f;
  return first;
}

TEST(VideoCodec, LateJoinersAndLossesRecoverWithinTwoRefreshPeriods) {
  for (const bool intra_refresh : {true, false}) {
    SCOPED_TRACE(intra_refresh ? "intra refresh" : "IDR every refresh_s");
    VideoSettings s;
    s.intra_refresh = intra_refresh;
    const int period = s.refreshFrames();
    const auto packets = stream(6 * period, s);
    // A late joiner: nothing shows before a key and a whole refresh.
    VideoReceiver late;
    const int first = feed(late, packets, period / 3, 6 * period);
    EXPECT_GT(first, period / 3);
    EXPECT_LE(first, period / 3 + 2 * period);
    EXPECT_EQ(shownFrame(late), 6 * period - 1);
    // A lost access unit: the picture stays the last good one until the next key.
    VideoReceiver lossy;
    feed(lossy, packets, 0, 2 * period + 2);
    EXPECT_EQ(shownFrame(lossy), 2 * period + 1);
    const int back = feed(lossy, packets, 2 * period + 3, 6 * period);  // 2 * period + 2 lost
    EXPECT_EQ(lossy.stats().lost, 1u);
    EXPECT_GT(back, 2 * period + 3);
    EXPECT_LE(back, 2 * period + 3 + 2 * period);
    EXPECT_EQ(shownFrame(lossy), 6 * period - 1);
    // Not shown: nothing decoded; shown again: from the next key on.
    VideoReceiver hidden;
    hidden.setShown(false);
    feed(hidden, packets, 0, period + 1);
    EXPECT_EQ(hidden.stats().decoded, 0u);
    EXPECT_TRUE(hidden.picture().empty());
    hidden.setShown(true);
    EXPECT_GT(feed(hidden, packets, period + 1, 6 * period), period + 1);
    EXPECT_EQ(shownFrame(hidden), 6 * period - 1);
  }
}

TEST(VideoCodec, CorruptAccessUnitsKeepTheLastGoodPicture) {
  VideoSettings s;
  const int period = s.refreshFrames();
  const auto packets = stream(5 * period, s);
  std::mt19937 rng(7);
  VideoReceiver r;
  feed(r, packets, 0, period + 5);
  const int good = shownFrame(r);
  ASSERT_EQ(good, period + 4);
  // Every later access unit of the next period damaged in its payload: random bytes, some
  // truncated to a few bytes; the packets themselves stay valid (their checks pass).
  for (int f = period + 5; f < 2 * period + 5; ++f) {
    for (const auto& b : packets[size_t(f)]) {
      VideoPacket p = parse(b);
      if (f % 3 == 0) p.payload.resize(std::min<size_t>(p.payload.size(), 7));
      for (size_t i = 5; i < p.payload.size(); i += 3) p.payload[i] = uint8_t(rng());
      r.receive(p);
      EXPECT_EQ(shownFrame(r), good) << "the picture changed while its access units were damaged";
    }
  }
  EXPECT_GT(r.stats().errors + r.stats().skipped, 0u);
  // Clean access units again: back to a good picture within two refresh periods.
  feed(r, packets, 2 * period + 5, 5 * period);
  EXPECT_EQ(shownFrame(r), 5 * period - 1);
}

TEST(VideoSource, AFileIsReadScaledAndLooped) {
  // A raw H.264 stream (Annex B, what the encoder makes) is a file libavformat reads.
  const std::filesystem::path file = std::filesystem::temp_directory_path() /
                                     ("tessera-video-" + std::to_string(getpid()) + ".h264");
  {
    VideoSettings s;
    s.width = 320;
    s.height = 240;
    s.intra_refresh = false;  // starts with an IDR, as a file does
    VideoEncoder encoder(s);
    std::ofstream out(file, std::ios::binary);
    VideoPicture p;
    for (uint32_t f = 0; f < 20; ++f) {
      drawTestPattern(p, s.width, s.height, {f, 5000u + f});
      const EncodedVideo unit = encoder.encode(p);
      out.write(reinterpret_cast<const char*>(unit.bytes.data()),
                std::streamsize(unit.bytes.size()));
    }
  }
  auto source = openVideoSource(file.string(), 640, 480, 30);
  EXPECT_NE(source->describe().find("h264 320x240"), std::string::npos) << source->describe();
  VideoPicture p;
  std::vector<uint32_t> frames;
  for (int i = 0; i < 30; ++i) {
    ASSERT_TRUE(source->grab(p));
    ASSERT_EQ(p.width, 640);
    ASSERT_EQ(p.height, 480);
    const auto code = readTestPattern(p.rgba.data(), p.width, 0, 0, p.width, p.height);
    ASSERT_TRUE(code) << "picture " << i;
    frames.push_back(code->frame);
  }
  std::filesystem::remove(file);
  for (uint32_t f = 0; f < 20; ++f) EXPECT_EQ(frames[f], f);
  EXPECT_EQ(frames[20], 0u) << "the file starts over at its end";
  EXPECT_EQ(frames[29], 9u);
  // What cannot be opened says what and where.
  try {
    openVideoSource((file.string() + ".missing"), 640, 480, 30);
    FAIL() << "a missing file opened";
  } catch (const VideoError& e) {
    EXPECT_NE(std::string(e.what()).find(".missing: No such file"), std::string::npos) << e.what();
  }
  EXPECT_THROW(openVideoSource("test", 8, 8, 30), VideoError);
}

TEST(VideoPacket, RefusesWhatDoesNotCheck) {
  VideoPacket p;
  p.site = 2;
  p.frame = 77;
  p.key = true;
  p.chunk = 1;
  p.chunks = 3;
  p.width = 640;
  p.height = 480;
  p.payload.assign(100, 0xAB);
  const std::vector<uint8_t> bytes = encodeVideoPacket(p);
  VideoPacket q;
  ASSERT_EQ(decodeVideoPacket(bytes, q), std::nullopt);
  EXPECT_EQ(q.frame, 77u);
  EXPECT_EQ(q.chunk, 1);
  EXPECT_EQ(q.chunks, 3);
  EXPECT_TRUE(q.key);
  EXPECT_EQ(q.payload, p.payload);
  const auto refused = [&](std::vector<uint8_t> b, const std::string& says) {
    VideoPacket r;
    const auto why = decodeVideoPacket(b, r);
    ASSERT_TRUE(why) << says;
    EXPECT_NE(why->find(says), std::string::npos) << *why;
  };
  refused(std::vector<uint8_t>(bytes.begin(), bytes.begin() + 10), "shorter than the header");
  refused(std::vector<uint8_t>(bytes.begin(), bytes.end() - 1), "payload size 100 but 99");
  std::vector<uint8_t> big = bytes;
  big.resize(kMaxVideoPacketBytes + 1);
  refused(big, "more than the largest packet");
  auto patched = [&](size_t at, uint8_t v) {
    std::vector<uint8_t> b = bytes;
    b[at] = v;
    return b;
  };
  refused(patched(0, 9), "version 9");
  refused(patched(1, 2), "reserved bits");
  refused(patched(9, 0), "chunk count 0");
  refused(patched(9, kMaxVideoChunks + 1), "chunk count 65");
  refused(patched(8, 3), "chunk 3 of 3");
  refused(patched(11, 0x40), "picture size");
  // Chunks out of order still join; a chunk of an older unit is ignored.
  VideoAssembler a;
  VideoPacket c0 = p, c1 = p, c2 = p;
  c0.chunk = 0;
  c2.chunk = 2;
  EXPECT_FALSE(a.add(c2));
  EXPECT_FALSE(a.add(c0));
  const auto unit = a.add(c1);
  ASSERT_TRUE(unit);
  EXPECT_EQ(unit->bytes.size(), 300u);
  EXPECT_FALSE(a.add(c1)) << "a duplicate of a completed unit";
}

}  // namespace
