// WAV files (media/voice_wav.h): round trips, stereo mixed down, other rates resampled to
// 48 kHz, and every bad file refused with its name and what is wrong.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>

#include <tessera/media/voice_wav.h>

#include "../support/temp_dir.h"
#include "../support/voice_path.h"

namespace {

using namespace tessera::media;
namespace fs = std::filesystem;

std::string refusal(const fs::path& path) {
  try {
    readVoiceWav(path);
  } catch (const WavError& e) {
    return e.what();
  }
  return "";
}

void writeBytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

TEST(VoiceWav, MonoRoundTripIsExactTo16Bits) {
  tessera::test::TempDir dir;
  std::vector<float> x = tessera::test::tone(1000, 0.5);
  x[10] = 3.0f;  // clamped, never wrapped
  x[11] = -3.0f;
  writeWav(dir / "a.wav", x);
  const WavAudio a = readWav(dir / "a.wav");
  EXPECT_EQ(a.rate, 48000);
  EXPECT_EQ(a.channels, 1);
  ASSERT_EQ(a.samples.size(), x.size());
  EXPECT_EQ(a.samples[10], 32767);
  EXPECT_EQ(a.samples[11], -32767);
  const std::vector<float> y = readVoiceWav(dir / "a.wav");
  for (size_t i = 20; i < x.size(); ++i) ASSERT_NEAR(y[i], x[i], 1.0 / 32768 + 1e-6);
}

TEST(VoiceWav, StereoIsMixedDown) {
  tessera::test::TempDir dir;
  std::vector<float> lr;
  for (int i = 0; i < 4800; ++i) {
    lr.push_back(0.5f);
    lr.push_back(-0.25f);
  }
  writeWav(dir / "s.wav", lr, 48000, 2);
  const std::vector<float> y = readVoiceWav(dir / "s.wav");
  ASSERT_EQ(y.size(), 4800u);
  for (float v : y) ASSERT_NEAR(v, 0.125f, 1e-4);
}

TEST(VoiceWav, OtherRatesAreResampledTo48k) {
  tessera::test::TempDir dir;
  for (int rate : {22050, 16000, 44100, 96000}) {
    // A 1 kHz tone at `rate` becomes a 1 kHz tone at 48 kHz (against the ideal one).
    std::vector<float> x(static_cast<size_t>(rate));
    for (size_t n = 0; n < x.size(); ++n)
      x[n] = 0.5f * float(std::sin(2 * std::numbers::pi * 1000 * double(n) / rate));
    const fs::path path = dir / ("r" + std::to_string(rate) + ".wav");
    writeWav(path, x, rate);
    const std::vector<float> y = readVoiceWav(path);
    EXPECT_NEAR(double(y.size()), 48000, 1) << rate;
    const std::vector<float> ideal = tessera::test::tone(1000, 1, 0.5f);
    EXPECT_GT(tessera::test::snrDb(ideal, y, 0, 2000, 46000), 40) << rate << " Hz";
  }
}

TEST(VoiceWav, TheEspeakSentenceReadsAt48k) {
  tessera::test::TempDir dir;
  const auto speech = tessera::test::espeakSpeech(dir / "e.wav", "Hello wall");
  if (!speech) GTEST_SKIP() << "espeak-ng is not installed";
  EXPECT_EQ(readWav(dir / "e.wav").rate, 22050);  // what espeak-ng writes
  EXPECT_GT(speech->size(), 24000u);
}

TEST(VoiceWav, BadFilesAreRefusedByNameAndReason) {
  tessera::test::TempDir dir;
  std::vector<float> x(480, 0.1f);
  writeWav(dir / "good.wav", x);
  const std::vector<uint8_t> good = tessera::test::readBytes(dir / "good.wav");
  const auto variant = [&](const std::string& name, auto change) {
    std::vector<uint8_t> b = good;
    change(b);
    writeBytes(dir / name, b);
    return refusal(dir / name);
  };
  const auto has = [](const std::string& what, const std::string& text) {
    EXPECT_NE(what.find(text), std::string::npos) << what;
  };
  has(refusal(dir / "missing.wav"), "missing.wav: No such file");
  has(refusal(dir.path()), "not a regular file");
  has(variant("text.wav",
              [](auto& b) {
                b.assign({'h', 'e', 'l', 'l', 'o'});
              }),
      "text.wav: not a WAV file");
  has(variant("cut.wav", [](auto& b) { b.resize(100); }), "cut.wav: truncated: the data chunk");
  has(variant("24bit.wav", [](auto& b) { b[34] = 24; }), "24bit.wav: 24-bit samples");
  has(variant("float.wav", [](auto& b) { b[20] = 3; }), "format 3, expected PCM");
  has(variant("six.wav", [](auto& b) { b[22] = 6; }), "6 channels, expected mono or stereo");
  has(variant("slow.wav",
              [](auto& b) {
                b[24] = 100;
                b[25] = 0;
                b[26] = 0;
              }),
      "sample rate 100 Hz");
  has(variant("align.wav", [](auto& b) { b[32] = 4; }), "block align 4");
  has(variant("nodata.wav", [](auto& b) { b[36] = 'x'; }), "nodata.wav: no data chunk");
  has(variant("long.wav",
              [](auto& b) {
                b[36] = 'x';
                b[42] = 1;
              }),
      "truncated: the 'xata' chunk");
  has(variant("odd.wav",
              [](auto& b) {
                b[40] = uint8_t(b[40] - 1);
                b.pop_back();
              }),
      "not whole sample frames");
  has(variant("order.wav", [](auto& b) { b[12] = 'j'; }), "the data chunk comes before the fmt");
  EXPECT_EQ(refusal(dir / "good.wav"), "");
}

TEST(VoiceWav, WritingWhereItCannotSaysWhere) {
  try {
    writeWav("/nonexistent-folder/out.wav", std::vector<float>(10));
    FAIL() << "no error";
  } catch (const WavError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-folder/out.wav"), std::string::npos)
        << e.what();
  }
}

}  // namespace
