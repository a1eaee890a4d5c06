// libFuzzer target: WAV files from outside (media/voice_wav.h) parsed from memory and turned
// into a 48 kHz mono voice stream (mixdown and resampling). A WavError is the only failure
// allowed.
#include <cstdint>
#include <span>

#include <tessera/media/voice_wav.h>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const tessera::media::WavAudio audio =
        tessera::media::parseWav(std::span<const uint8_t>(data, size), "fuzz.wav");
    // Long inputs at low rates resample slowly; a few seconds of output are plenty.
    if (audio.samples.size() < 200000) (void)tessera::media::toVoice(audio);
  } catch (const tessera::media::WavError&) {
  }
  return 0;
}
