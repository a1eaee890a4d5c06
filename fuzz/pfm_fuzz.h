// The body of the PFM fuzz target and its regression replay: bytes read as a projector's warp or
// blend map (render/projector_pass.h readPfm(); a wall's files and MPCDI warps are outside
// bytes). RenderError is the only failure allowed; a map read holds exactly its values.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <span>

#include <tessera/render/projector_pass.h>

namespace tessera::fuzz {

inline int readPfm(const uint8_t* data, size_t size) {
  try {
    const render::FloatImage f = render::readPfm(std::span(data, size), "fuzz.pfm");
    if (f.width == 0 || f.height == 0 || (f.channels != 1 && f.channels != 3) ||
        f.values.size() != size_t(f.width) * f.height * f.channels) {
      std::fprintf(stderr, "pfm fuzz: broken invariant: %ux%u x%u, %zu values\n", f.width,
                   f.height, f.channels, f.values.size());
      std::abort();
    }
  } catch (const render::RenderError&) {
  }
  return 0;
}

}  // namespace tessera::fuzz
