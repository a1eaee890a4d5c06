#include <tessera/media/voice_alsa.h>

#include <alsa/asoundlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>

#include <tessera/media/voice_codec.h>
#include <tessera/core/check.h>

namespace tessera::media {
namespace {

const char* directionName(AlsaPcm::Direction d) {
  return d == AlsaPcm::Direction::kCapture ? "capture" : "playback";
}

/// Powers of two: an xrun storm (a stalled loop) says so without flooding the log.
bool worthSaying(uint64_t n) {
  return (n & (n - 1)) == 0;
}

/// Frames of `frame_samples` whole by clock time `now`, plus kAlsaMaxAhead_s of them.
uint64_t mostBy(double now, int frame_samples) {
  const double frames = (std::max(0.0, now) + kAlsaMaxAhead_s) * kVoiceRate / frame_samples;
  return uint64_t(std::floor(frames));
}

}  // namespace

std::optional<std::string> alsaDeviceOf(const std::string& audio) {
  constexpr std::string_view kPrefix = "alsa:";
  if (audio.compare(0, kPrefix.size(), kPrefix) != 0) return std::nullopt;
  std::string device = audio.substr(kPrefix.size());
  if (device.empty())
    throw AlsaError("media::alsaDeviceOf(): " + audio +
                    ": no device after alsa: (expected e.g. alsa:default or alsa:hw:0,0)");
  return device;
}

void AlsaPcm::Close::operator()(_snd_pcm* pcm) const noexcept {
  snd_pcm_close(pcm);
}

void AlsaPcm::fail(const char* what, int err) const {
  throw AlsaError(std::string("media::AlsaPcm: ") + directionName(mDirection) + " device '" +
                  mDevice + "': " + what + snd_strerror(err));
}

AlsaPcm::AlsaPcm(const std::string& device, Direction direction, int frame_samples,
                 int buffer_frames, std::function<void(const std::string&)> say)
    : mDevice(device), mDirection(direction), mFrameSamples(frame_samples), mSay(std::move(say)) {
  if (frame_samples <= 0 || frame_samples > kMaxVoiceFrameSamples || buffer_frames < 2)
    throw AlsaError("media::AlsaPcm: " + device + ": a frame of " + std::to_string(frame_samples) +
                    " samples and a buffer of " + std::to_string(buffer_frames) +
                    " frames; expected at most 960 samples and at least 2 frames");
  if (!mSay) mSay = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
  // The plug layer converts what the card cannot do itself (Section "PCM plugins", alsa-lib).
  std::string name = device;
  if (name.compare(0, 3, "hw:") == 0) name = "plug" + name;
  snd_pcm_t* pcm = nullptr;
  int err = snd_pcm_open(
      &pcm, name.c_str(),
      direction == Direction::kCapture ? SND_PCM_STREAM_CAPTURE : SND_PCM_STREAM_PLAYBACK, 0);
  if (err < 0) fail("cannot open it: ", err);
  mPcm.reset(pcm);

  snd_pcm_hw_params_t* hw = nullptr;
  snd_pcm_hw_params_alloca(&hw);
  if ((err = snd_pcm_hw_params_any(pcm, hw)) < 0) fail("no configuration: ", err);
  if ((err = snd_pcm_hw_params_set_rate_resample(pcm, hw, 1)) < 0) fail("cannot resample: ", err);
  if ((err = snd_pcm_hw_params_set_access(pcm, hw, SND_PCM_ACCESS_RW_INTERLEAVED)) < 0)
    fail("no interleaved read/write access: ", err);
  if ((err = snd_pcm_hw_params_set_format(pcm, hw, SND_PCM_FORMAT_S16)) < 0)
    fail("no 16-bit samples: ", err);
  if ((err = snd_pcm_hw_params_set_channels(pcm, hw, 1)) < 0) fail("no mono: ", err);
  if ((err = snd_pcm_hw_params_set_rate(pcm, hw, kVoiceRate, 0)) < 0) fail("no 48 kHz: ", err);
  snd_pcm_uframes_t period = snd_pcm_uframes_t(frame_samples);
  int dir = 0;
  if ((err = snd_pcm_hw_params_set_period_size_near(pcm, hw, &period, &dir)) < 0)
    fail("no period near one frame: ", err);
  snd_pcm_uframes_t buffer = snd_pcm_uframes_t(frame_samples) * snd_pcm_uframes_t(buffer_frames);
  if ((err = snd_pcm_hw_params_set_buffer_size_near(pcm, hw, &buffer)) < 0)
    fail("no buffer of that size: ", err);
  if ((err = snd_pcm_hw_params(pcm, hw)) < 0) fail("cannot set 48 kHz mono S16: ", err);
  mPeriod = period;
  mBuffer = buffer;
  if (mBuffer < snd_pcm_uframes_t(frame_samples) * 2)
    throw AlsaError("media::AlsaPcm: " + std::string(directionName(direction)) + " device '" +
                    device + "': a buffer of " + std::to_string(mBuffer) +
                    " samples, expected at least two frames");

  snd_pcm_sw_params_t* sw = nullptr;
  snd_pcm_sw_params_alloca(&sw);
  if ((err = snd_pcm_sw_params_current(pcm, sw)) < 0) fail("no software parameters: ", err);
  // Playback starts once two frames are queued, so the first write does not underrun at once.
  const snd_pcm_uframes_t start =
      direction == Direction::kPlayback ? snd_pcm_uframes_t(frame_samples) * 2 : 1;
  if ((err = snd_pcm_sw_params_set_start_threshold(pcm, sw, start)) < 0 ||
      (err = snd_pcm_sw_params_set_avail_min(pcm, sw, snd_pcm_uframes_t(frame_samples))) < 0 ||
      (err = snd_pcm_sw_params(pcm, sw)) < 0)
    fail("cannot set the start threshold: ", err);
  if ((err = snd_pcm_prepare(pcm)) < 0) fail("cannot prepare it: ", err);
  if (direction == Direction::kCapture && (err = snd_pcm_start(pcm)) < 0)
    fail("cannot start capturing: ", err);
  mPcm16.resize(size_t(frame_samples));
}

AlsaPcm::~AlsaPcm() = default;
AlsaPcm::AlsaPcm(AlsaPcm&&) noexcept = default;
AlsaPcm& AlsaPcm::operator=(AlsaPcm&&) noexcept = default;

void AlsaPcm::recover(long err, const char* what) {
  // -EPIPE: an overrun (capture) or underrun (playback); -ESTRPIPE: the system suspended.
  const int r = snd_pcm_recover(mPcm.get(), int(err), 1);
  if (r < 0) fail(what, int(err));
  ++mXruns;
  if (worthSaying(mXruns))
    mSay("media::AlsaPcm: " + std::string(directionName(mDirection)) + " device '" + mDevice +
         "': " +
         (err == -EPIPE ? (mDirection == Direction::kCapture ? "overrun" : "underrun")
                        : std::string(snd_strerror(int(err)))) +
         ", recovered (" + std::to_string(mXruns) + " so far)");
  if (mDirection == Direction::kCapture) snd_pcm_start(mPcm.get());
}

void AlsaPcm::restart() {
  int err = snd_pcm_drop(mPcm.get());
  if (err >= 0) err = snd_pcm_prepare(mPcm.get());
  if (err >= 0 && mDirection == Direction::kCapture) err = snd_pcm_start(mPcm.get());
  if (err < 0) fail("cannot restart it: ", err);
}

size_t AlsaPcm::available() {
  snd_pcm_sframes_t n = snd_pcm_avail(mPcm.get());
  if (n < 0) {
    recover(n, "lost it: ");
    n = snd_pcm_avail(mPcm.get());
    if (n < 0) fail("lost it: ", int(n));
  }
  return size_t(n) / size_t(mFrameSamples);
}

void AlsaPcm::read(std::span<float> frame) {
  TESSERA_CHECK(mDirection == Direction::kCapture && frame.size() == size_t(mFrameSamples),
                "AlsaPcm::read(): a capture device and one frame");
  size_t got = 0;
  while (got < frame.size()) {
    const snd_pcm_sframes_t n =
        snd_pcm_readi(mPcm.get(), mPcm16.data() + got, snd_pcm_uframes_t(frame.size() - got));
    if (n == -EAGAIN) continue;
    if (n < 0) {
      recover(n, "cannot read: ");
      continue;
    }
    got += size_t(n);
  }
  for (size_t i = 0; i < frame.size(); ++i) frame[i] = float(mPcm16[i]) / 32768.0f;
}

void AlsaPcm::write(std::span<const float> frame) {
  TESSERA_CHECK(mDirection == Direction::kPlayback && frame.size() == size_t(mFrameSamples),
                "AlsaPcm::write(): a playback device and one frame");
  for (size_t i = 0; i < frame.size(); ++i)
    mPcm16[i] = int16_t(std::lrint(std::clamp(frame[i], -1.0f, 32767.0f / 32768.0f) * 32768.0f));
  size_t put = 0;
  while (put < frame.size()) {
    const snd_pcm_sframes_t n =
        snd_pcm_writei(mPcm.get(), mPcm16.data() + put, snd_pcm_uframes_t(frame.size() - put));
    if (n == -EAGAIN) continue;
    if (n < 0) {
      recover(n, "cannot write: ");
      continue;
    }
    put += size_t(n);
  }
}

size_t AlsaPcm::queued() {
  const snd_pcm_state_t state = snd_pcm_state(mPcm.get());
  if (state != SND_PCM_STATE_RUNNING && state != SND_PCM_STATE_PREPARED) return 0;
  const snd_pcm_sframes_t free = snd_pcm_avail(mPcm.get());
  if (free < 0) return 0;  // an xrun: nothing queued (available() or write() recovers it)
  return mBuffer > size_t(free) ? mBuffer - size_t(free) : 0;
}

std::string AlsaPcm::describe() const {
  return std::string(directionName(mDirection)) + " device '" + mDevice + "' (period " +
         std::to_string(mPeriod) + " samples, buffer " + std::to_string(mBuffer) + ")";
}

AlsaMicrophone::AlsaMicrophone(const std::string& device, int frame_samples,
                               std::function<void(const std::string&)> say)
    : mPcm(device, AlsaPcm::Direction::kCapture, frame_samples, 25, std::move(say)),
      mFrame(size_t(frame_samples)) {}

void AlsaMicrophone::pump(double now, const std::function<void(std::span<const float>)>& frame) {
  if (!mStarted) {  // what it captured before the loop began (joining, preparing) is not sent
    mPcm.restart();
    mStarted = true;
  }
  const uint64_t most = mostBy(now, mPcm.frameSamples());
  for (size_t ready = mPcm.available(); ready > 0 && mFrames < most; --ready, ++mFrames) {
    mPcm.read(mFrame);
    frame(mFrame);
  }
}

AlsaSpeaker::AlsaSpeaker(const std::string& device, int frame_samples, double lead_s,
                         std::function<void(const std::string&)> say)
    : mPcm(device, AlsaPcm::Direction::kPlayback, frame_samples, 25, std::move(say)),
      mLead(size_t(std::max(2.0, std::ceil(lead_s * kVoiceRate / frame_samples))) *
            size_t(frame_samples)),
      mFrame(size_t(frame_samples)) {}

void AlsaSpeaker::pump(double now, const std::function<void(double, std::span<float>)>& fill) {
  const double frame_s = double(mPcm.frameSamples()) / kVoiceRate;
  const uint64_t most = mostBy(now, mPcm.frameSamples());
  while (mFrames < most && mPcm.available() > 0) {
    const size_t queued = mPcm.queued();
    if (queued >= mLead) break;
    // When it plays: after what is queued; never before the frame written last has played
    // (a device without a clock queues nothing).
    const double t = std::max(now + double(queued) / kVoiceRate, mLast + frame_s);
    fill(t, mFrame);
    mPcm.write(mFrame);
    mLast = t;
    ++mFrames;
  }
}

}  // namespace tessera::media
