// The body of the note picture fuzz target and its regression replay: bytes from an image item
// (a database file or the file it names: outside bytes) decoded and scaled for the wall
// (annotate/note_picture.h). std::runtime_error is the only failure allowed; a decoded picture
// fits the square it was asked for and holds exactly its pixels.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <span>
#include <stdexcept>

#include <tessera/annotate/note_picture.h>

namespace tessera::fuzz {

inline int decodePicture(const uint8_t* data, size_t size) {
  constexpr uint32_t kFit = 64;
  try {
    const annotate::NotePicture p = annotate::decodeNotePicture(std::span(data, size), kFit);
    if (p.width == 0 || p.height == 0 || p.width > kFit || p.height > kFit ||
        p.rgba.size() != size_t(p.width) * p.height * 4) {
      std::fprintf(stderr, "picture fuzz: broken invariant: %ux%u, %zu bytes\n", p.width,
                   p.height, p.rgba.size());
      std::abort();
    }
  } catch (const std::runtime_error&) {
  }
  return 0;
}

}  // namespace tessera::fuzz
