#include <tessera/annotate/note_picture.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <stdexcept>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/error.h>
#include <libavutil/frame.h>
#include <libswscale/swscale.h>
}

namespace tessera::annotate {

namespace {

struct CodecFree {
  void operator()(AVCodecContext* c) const { avcodec_free_context(&c); }
  void operator()(AVFrame* f) const { av_frame_free(&f); }
  void operator()(AVPacket* p) const { av_packet_free(&p); }
  void operator()(SwsContext* s) const { sws_freeContext(s); }
};

std::string avError(int code) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(code, text, sizeof text);
  return text;
}

bool startsWith(std::span<const uint8_t> bytes, std::string_view magic, size_t at = 0) {
  return bytes.size() >= at + magic.size() && std::memcmp(bytes.data() + at, magic.data(), magic.size()) == 0;
}

/// The still-picture codec whose signature starts `bytes`, or AV_CODEC_ID_NONE.
AVCodecID codecOf(std::span<const uint8_t> bytes) {
  if (startsWith(bytes, "\x89PNG\r\n\x1a\n")) return AV_CODEC_ID_PNG;
  if (startsWith(bytes, "\xff\xd8\xff")) return AV_CODEC_ID_MJPEG;
  if (startsWith(bytes, "GIF87a") || startsWith(bytes, "GIF89a")) return AV_CODEC_ID_GIF;
  if (startsWith(bytes, "RIFF") && startsWith(bytes, "WEBP", 8)) return AV_CODEC_ID_WEBP;
  if (startsWith(bytes, std::string_view("II*\0", 4)) || startsWith(bytes, std::string_view("MM\0*", 4)))
    return AV_CODEC_ID_TIFF;
  if (startsWith(bytes, "BM") && bytes.size() >= 54) return AV_CODEC_ID_BMP;
  return AV_CODEC_ID_NONE;
}

}  // namespace

NotePicture decodeNotePicture(std::span<const uint8_t> bytes, uint32_t max_px) {
  if (max_px == 0) throw std::runtime_error("a picture must fit at least 1 pixel");
  if (bytes.size() > kMaxNoteImageBytes)
    throw std::runtime_error("an image of " + std::to_string(bytes.size()) + " bytes: at most " +
                             std::to_string(kMaxNoteImageBytes));
  const AVCodecID id = codecOf(bytes);
  if (id == AV_CODEC_ID_NONE)
    throw std::runtime_error("not an image this build reads (PNG, JPEG, GIF, WebP, TIFF, BMP)");
  const AVCodec* codec = avcodec_find_decoder(id);
  if (!codec) throw std::runtime_error(std::string("no ") + avcodec_get_name(id) + " decoder in libavcodec");
  std::unique_ptr<AVCodecContext, CodecFree> c(avcodec_alloc_context3(codec));
  std::unique_ptr<AVFrame, CodecFree> frame(av_frame_alloc());
  std::unique_ptr<AVPacket, CodecFree> packet(av_packet_alloc());
  if (!c || !frame || !packet) throw std::runtime_error("out of memory for the image decoder");
  c->thread_count = 1;
  // Refused before the decoder allocates the picture (a small file may declare a huge one).
  c->max_pixels = int64_t(kMaxNoteImageSide) * kMaxNoteImageSide;
  c->err_recognition = AV_EF_EXPLODE;
  if (const int r = avcodec_open2(c.get(), codec, nullptr); r < 0)
    throw std::runtime_error("image decoder: " + avError(r));
  // The decoder may read up to AV_INPUT_BUFFER_PADDING_SIZE past the end: a padded copy.
  std::vector<uint8_t> padded(bytes.size() + AV_INPUT_BUFFER_PADDING_SIZE, 0);
  std::memcpy(padded.data(), bytes.data(), bytes.size());
  packet->data = padded.data();
  packet->size = int(bytes.size());
  packet->flags = AV_PKT_FLAG_KEY;
  int r = avcodec_send_packet(c.get(), packet.get());
  if (r < 0) throw std::runtime_error(std::string(avcodec_get_name(id)) + ": " + avError(r));
  (void)avcodec_send_packet(c.get(), nullptr);  // end of stream: the picture comes out now
  r = avcodec_receive_frame(c.get(), frame.get());
  if (r < 0) throw std::runtime_error(std::string(avcodec_get_name(id)) + ": " + avError(r));
  const AVFrame* f = frame.get();
  if ((f->flags & AV_FRAME_FLAG_CORRUPT) || f->decode_error_flags != 0)
    throw std::runtime_error(std::string(avcodec_get_name(id)) + ": a damaged picture");
  if (f->width <= 0 || f->height <= 0 || f->width > int(kMaxNoteImageSide) ||
      f->height > int(kMaxNoteImageSide))
    throw std::runtime_error("a " + std::to_string(f->width) + "x" + std::to_string(f->height) +
                             " picture: at most " + std::to_string(kMaxNoteImageSide) + " a side");
  const double scale = std::min(1.0, double(max_px) / double(std::max(f->width, f->height)));
  NotePicture out;
  out.width = uint32_t(std::clamp<long>(std::lround(f->width * scale), 1, long(max_px)));
  out.height = uint32_t(std::clamp<long>(std::lround(f->height * scale), 1, long(max_px)));
  std::unique_ptr<SwsContext, CodecFree> sws(
      sws_getContext(f->width, f->height, AVPixelFormat(f->format), int(out.width),
                     int(out.height), AV_PIX_FMT_RGBA, SWS_AREA, nullptr, nullptr, nullptr));
  if (!sws)
    throw std::runtime_error(std::string("no conversion from the pixel format ") +
                             std::to_string(f->format) + " of this " + avcodec_get_name(id));
  out.rgba.resize(size_t(out.width) * out.height * 4);
  uint8_t* dst[4] = {out.rgba.data(), nullptr, nullptr, nullptr};
  const int stride[4] = {int(out.width) * 4, 0, 0, 0};
  sws_scale(sws.get(), f->data, f->linesize, 0, f->height, dst, stride);
  return out;
}

NotePicture readNotePicture(const std::filesystem::path& path, const std::filesystem::path& base,
                            uint32_t max_px) {
  const std::filesystem::path file = path.is_relative() ? base / path : path;
  try {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec))
      throw std::runtime_error(ec ? ec.message() : "not a regular file");
    const uintmax_t size = std::filesystem::file_size(file, ec);
    if (ec) throw std::runtime_error(ec.message());
    if (size > kMaxNoteImageBytes)
      throw std::runtime_error(std::to_string(size) + " bytes: at most " +
                               std::to_string(kMaxNoteImageBytes));
    std::ifstream in(file, std::ios::binary);
    std::vector<uint8_t> bytes(size);
    if (!in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size)))
      throw std::runtime_error("cannot read it");
    return decodeNotePicture(bytes, max_px);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(file.string() + ": " + e.what());
  }
}

}  // namespace tessera::annotate
