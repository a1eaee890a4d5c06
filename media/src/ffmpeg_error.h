// FFmpeg's error codes as text, for the messages of the video codec and sources.
#pragma once

#include <string>

extern "C" {
#include <libavutil/error.h>
}

namespace tessera::media {

inline std::string avError(int code) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(code, text, sizeof text);
  return text;
}

}  // namespace tessera::media
