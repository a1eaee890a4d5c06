// Voice: a sound device through ALSA (alsa-lib, libasound2 from Debian): a site's or
// the wall room's microphone and speaker, as the voice path takes them: 48 kHz mono, whole
// frames (10 or 20 ms), 16-bit samples on the device and floats in [-1, 1] here.
//
// The command lines name a device as "alsa:DEVICE" (`alsa:default`, `alsa:hw:0,0`,
// `alsa:null`) where they otherwise take a WAV path. "hw:C,D" is opened as "plughw:C,D", so
// alsa-lib's plug layer converts the format, channel count and rate when the card wants others;
// every other name is opened as given ("default" already goes through plug on usual setups).
//
// The device paces the stream: read() and write() block until a frame fits, available() says
// how many do without blocking (a loop that must not block calls it first). An overrun or
// underrun (the caller was late) is recovered with snd_pcm_recover() and said through the
// `say` callback. Not thread-safe: one device, one thread.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

struct _snd_pcm;

namespace tessera::media {

/// A sound device that cannot be opened, set up or used; what() names the device and gives
/// alsa-lib's reason ("media::AlsaPcm: capture device 'nosuchdevice': No such file or
/// directory").
struct AlsaError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The device named by a command line's audio argument: "alsa:DEVICE" gives DEVICE, anything
/// else (a WAV path) nothing. Throws AlsaError for "alsa:" with no device.
std::optional<std::string> alsaDeviceOf(const std::string& audio);

class AlsaPcm {
 public:
  enum class Direction { kCapture, kPlayback };

  /// Opens `device` for `direction` at 48 kHz mono S16 with a period of `frame_samples`
  /// (480 or 960: 10 or 20 ms) and a buffer of `buffer_frames` such frames (the most a late
  /// caller can catch up on before an xrun). Capture starts at once. `say` hears about xruns
  /// (by default a line on stderr). Throws AlsaError naming the device and alsa-lib's reason.
  AlsaPcm(const std::string& device, Direction direction, int frame_samples, int buffer_frames = 25,
          std::function<void(const std::string&)> say = {});
  ~AlsaPcm();
  AlsaPcm(AlsaPcm&&) noexcept;
  AlsaPcm& operator=(AlsaPcm&&) noexcept;
  AlsaPcm(const AlsaPcm&) = delete;
  AlsaPcm& operator=(const AlsaPcm&) = delete;

  /// Drops what is captured or queued and starts again (capture: capturing from now).
  void restart();
  /// Whole frames that read() or write() handles now without blocking (recovers an xrun first).
  size_t available();
  /// Capture: reads one frame (frameSamples() samples), blocking until the device has it.
  void read(std::span<float> frame);
  /// Playback: writes one frame (frameSamples() samples), blocking until the device has room.
  void write(std::span<const float> frame);
  /// Playback: samples written and not yet played (how late a sample written now is heard);
  /// 0 before the first write and after an underrun.
  size_t queued();

  int frameSamples() const { return mFrameSamples; }
  /// xruns recovered so far (overruns on capture, underruns on playback).
  uint64_t xruns() const { return mXruns; }
  /// "capture device 'default' (period 960 samples, buffer 24000)".
  std::string describe() const;

 private:
  void recover(long err, const char* what);
  [[noreturn]] void fail(const char* what, int err) const;

  struct Close {
    void operator()(_snd_pcm* pcm) const noexcept;
  };
  std::unique_ptr<_snd_pcm, Close> mPcm;
  std::string mDevice;
  Direction mDirection = Direction::kCapture;
  int mFrameSamples = 0;
  unsigned long mPeriod = 0, mBuffer = 0;  ///< what the device granted, samples
  std::vector<int16_t> mPcm16;
  uint64_t mXruns = 0;
  std::function<void(const std::string&)> mSay;
};

/// A sound device driven from a loop clocked by the session (seconds since the voice started),
/// as tessera-site and the master's bridge run: pump() never blocks, handles every frame the
/// device is ready for, and never runs more than kAlsaMaxAhead_s ahead of the clock (a device
/// with no clock of its own, such as alsa-lib's "null", which captures and plays at any speed,
/// is paced by the session's clock instead).
constexpr double kAlsaMaxAhead_s = 0.5;

class AlsaMicrophone {
 public:
  /// Throws AlsaError (AlsaPcm's).
  AlsaMicrophone(const std::string& device, int frame_samples,
                 std::function<void(const std::string&)> say = {});
  /// Hands every whole frame captured by `now` to `frame`, in order. The first call drops what
  /// the device captured before it (the clock starts there).
  void pump(double now, const std::function<void(std::span<const float>)>& frame);
  const AlsaPcm& pcm() const { return mPcm; }
  uint64_t frames() const { return mFrames; }

 private:
  AlsaPcm mPcm;
  std::vector<float> mFrame;
  uint64_t mFrames = 0;
  bool mStarted = false;
};

class AlsaSpeaker {
 public:
  /// `lead_s`: how much is kept queued on the device (the loop's period and its hiccups must
  /// fit in it, or the device underruns). Throws AlsaError (AlsaPcm's).
  AlsaSpeaker(const std::string& device, int frame_samples, double lead_s = 0.08,
              std::function<void(const std::string&)> say = {});
  /// Writes frames until `lead_s` is queued; `fill(t, frame)` gives the frame whose first
  /// sample plays at clock time `t` (increasing from call to call).
  void pump(double now, const std::function<void(double, std::span<float>)>& fill);
  const AlsaPcm& pcm() const { return mPcm; }
  uint64_t frames() const { return mFrames; }

 private:
  AlsaPcm mPcm;
  size_t mLead = 0;  ///< samples
  std::vector<float> mFrame;
  uint64_t mFrames = 0;
  double mLast = -1;  ///< clock time of the last frame written
};

}  // namespace tessera::media
