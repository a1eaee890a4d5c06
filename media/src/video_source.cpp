#include <tessera/media/video_source.h>

#include <atomic>
#include <cstdio>
#include <mutex>
#include <thread>

#include <tessera/media/video_pattern.h>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavdevice/avdevice.h>
#include <libavformat/avformat.h>
#include <libswscale/swscale.h>
}

#include "ffmpeg_error.h"

namespace tessera::media {

namespace {

class PatternSource final : public VideoSource {
 public:
  PatternSource(int w, int h) : mWidth(w), mHeight(h) {}
  bool grab(VideoPicture& out) override {
    drawTestPattern(out, mWidth, mHeight, {mFrame++, patternClockMs()});
    return true;
  }
  std::string describe() const override {
    return "test pattern " + std::to_string(mWidth) + "x" + std::to_string(mHeight);
  }

 private:
  int mWidth, mHeight;
  uint32_t mFrame = 0;
};

/// A demuxer and decoder over libavformat: files, and cameras through libavdevice.
class Demuxed {
 public:
  Demuxed(const std::string& url, const AVInputFormat* format, AVDictionary** options, int w, int h)
      : mUrl(url), mWidth(w), mHeight(h) {
    const auto fail = [&](const std::string& what, int r) {
      throw VideoError("media::openVideoSource(): " + url + ": " + what + avError(r));
    };
    if (const int r = avformat_open_input(&mFormat, url.c_str(), format, options); r < 0)
      fail("", r);
    if (const int r = avformat_find_stream_info(mFormat, nullptr); r < 0)
      fail("no stream information: ", r);
    const AVCodec* codec = nullptr;
    mStream = av_find_best_stream(mFormat, AVMEDIA_TYPE_VIDEO, -1, -1, &codec, 0);
    if (mStream < 0) fail("no video stream: ", mStream);
    mCodec = avcodec_alloc_context3(codec);
    if (!mCodec) fail("out of memory", 0);
    avcodec_parameters_to_context(mCodec, mFormat->streams[mStream]->codecpar);
    mCodec->thread_count = 1;
    if (const int r = avcodec_open2(mCodec, codec, nullptr); r < 0)
      fail(std::string("cannot open its ") + codec->name + " decoder: ", r);
    mFrame = av_frame_alloc();
    mPacket = av_packet_alloc();
    mDescription = std::string(codec->name) + " " + std::to_string(mCodec->width) + "x" +
                   std::to_string(mCodec->height);
  }
  ~Demuxed() {
    sws_freeContext(mSws);
    av_packet_free(&mPacket);
    av_frame_free(&mFrame);
    avcodec_free_context(&mCodec);
    avformat_close_input(&mFormat);
  }
  Demuxed(const Demuxed&) = delete;
  Demuxed& operator=(const Demuxed&) = delete;

  /// The next decoded picture, scaled into `out`; false at the end of the input.
  bool next(VideoPicture& out) {
    for (int guard = 0; guard < 100000; ++guard) {
      const int got = avcodec_receive_frame(mCodec, mFrame);
      if (got == 0) {
        convert(out);
        av_frame_unref(mFrame);
        return true;
      }
      if (got == AVERROR_EOF) return false;
      if (got != AVERROR(EAGAIN))
        throw VideoError("media::VideoSource: " + mUrl + ": decoding: " + avError(got));
      const int r = av_read_frame(mFormat, mPacket);
      if (r == AVERROR_EOF) {
        avcodec_send_packet(mCodec, nullptr);  // drain
        continue;
      }
      if (r == AVERROR(EAGAIN)) continue;
      if (r < 0) throw VideoError("media::VideoSource: " + mUrl + ": reading: " + avError(r));
      if (mPacket->stream_index == mStream) avcodec_send_packet(mCodec, mPacket);
      av_packet_unref(mPacket);
    }
    throw VideoError("media::VideoSource: " + mUrl + ": no picture in 100000 packets");
  }

  const std::string& description() const { return mDescription; }

 private:
  void convert(VideoPicture& out) {
    mSws = sws_getCachedContext(mSws, mFrame->width, mFrame->height, AVPixelFormat(mFrame->format),
                                mWidth, mHeight, AV_PIX_FMT_RGBA, SWS_BILINEAR, nullptr, nullptr,
                                nullptr);
    if (!mSws)
      throw VideoError("media::VideoSource: " + mUrl + ": cannot convert pixel format " +
                       std::to_string(mFrame->format));
    if (out.width != mWidth || out.height != mHeight) out.resize(mWidth, mHeight);
    uint8_t* dst[1] = {out.rgba.data()};
    const int stride[1] = {mWidth * 4};
    sws_scale(mSws, mFrame->data, mFrame->linesize, 0, mFrame->height, dst, stride);
  }

  std::string mUrl;
  int mWidth, mHeight;
  AVFormatContext* mFormat = nullptr;
  AVCodecContext* mCodec = nullptr;
  AVFrame* mFrame = nullptr;
  AVPacket* mPacket = nullptr;
  SwsContext* mSws = nullptr;
  int mStream = -1;
  std::string mDescription;
};

class FileSource final : public VideoSource {
 public:
  FileSource(const std::string& path, int w, int h)
      : mPath(path),
        mWidth(w),
        mHeight(h),
        mDemuxed(std::make_unique<Demuxed>(path, nullptr, nullptr, w, h)) {
    mDescription = "file " + path + " (" + mDemuxed->description() + ")";
  }
  bool grab(VideoPicture& out) override {
    if (mDemuxed->next(out)) return true;
    // At the end: open it again (seeking is not possible in every format, raw H.264 among them).
    mDemuxed = std::make_unique<Demuxed>(mPath, nullptr, nullptr, mWidth, mHeight);
    if (mDemuxed->next(out)) return true;
    throw VideoError("media::VideoSource: " + mDescription + ": no picture after starting over");
  }
  std::string describe() const override { return mDescription; }

 private:
  std::string mPath;
  int mWidth, mHeight;
  std::unique_ptr<Demuxed> mDemuxed;
  std::string mDescription;
};

/// A V4L2 camera; a thread reads it (av_read_frame waits for the camera) and keeps the latest
/// picture, which grab() takes.
class CameraSource final : public VideoSource {
 public:
  CameraSource(const std::string& device, int w, int h, double fps) {
    avdevice_register_all();
    const AVInputFormat* v4l2 = av_find_input_format("video4linux2");
    if (!v4l2)
      throw VideoError("media::openVideoSource(): " + device +
                       ": this libavdevice has no video4linux2 input");
    AVDictionary* options = nullptr;
    av_dict_set(&options, "video_size", (std::to_string(w) + "x" + std::to_string(h)).c_str(), 0);
    av_dict_set(&options, "framerate", std::to_string(int(fps + 0.5)).c_str(), 0);
    try {
      mDemuxed = std::make_unique<Demuxed>(device, v4l2, &options, w, h);
    } catch (...) {
      av_dict_free(&options);
      throw;
    }
    av_dict_free(&options);
    mDescription = "camera " + device + " (" + mDemuxed->description() + ")";
    mThread = std::thread([this] { capture(); });
  }
  ~CameraSource() override {
    mStop = true;
    if (mThread.joinable()) mThread.join();
  }
  bool grab(VideoPicture& out) override {
    std::lock_guard lock(mMutex);
    if (!mError.empty()) throw VideoError(mError);
    if (!mFresh) return false;
    std::swap(out, mLatest);
    mFresh = false;
    return true;
  }
  std::string describe() const override { return mDescription; }

 private:
  void capture() {
    VideoPicture p;
    while (!mStop) {
      try {
        if (!mDemuxed->next(p)) {
          std::lock_guard lock(mMutex);
          mError = "media::VideoSource: " + mDescription + ": the camera stopped";
          return;
        }
      } catch (const VideoError& e) {
        std::lock_guard lock(mMutex);
        mError = e.what();
        return;
      }
      std::lock_guard lock(mMutex);
      std::swap(p, mLatest);
      mFresh = true;
    }
  }

  std::unique_ptr<Demuxed> mDemuxed;
  std::string mDescription;
  std::thread mThread;
  std::atomic<bool> mStop{false};
  std::mutex mMutex;
  VideoPicture mLatest;
  bool mFresh = false;
  std::string mError;
};

}  // namespace

std::unique_ptr<VideoSource> openVideoSource(const std::string& spec, int width, int height,
                                             double fps) {
  if (width < 32 || height < 32 || width > kMaxVideoSide || height > kMaxVideoSide)
    throw VideoError("media::openVideoSource(): a picture size of " + std::to_string(width) + "x" +
                     std::to_string(height) + " (32.." + std::to_string(kMaxVideoSide) +
                     " each way)");
  if (spec == "test") return std::make_unique<PatternSource>(width, height);
  if (spec.rfind("/dev/video", 0) == 0)
    return std::make_unique<CameraSource>(spec, width, height, fps);
  return std::make_unique<FileSource>(spec, width, height);
}

}  // namespace tessera::media
