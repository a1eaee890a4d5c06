#include <tessera/render/gl_buffer.h>

#include <algorithm>
#include <cstring>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

namespace tessera::render {

GlBuffer::GlBuffer(size_t bytes, const void* data) : mBytes(std::max<size_t>(bytes, 16)) {
  // GL refuses empty storage; tiny contents are padded so the driver never reads past `data`.
  unsigned char padded[16] = {};
  if (data && bytes < 16) {
    std::memcpy(padded, data, bytes);
    data = padded;
  }
  glCreateBuffers(1, &mName);
  glNamedBufferStorage(mName, GLsizeiptr(mBytes), data, 0);
}

GlBuffer::~GlBuffer() {
  if (mName) glDeleteBuffers(1, &mName);
}

}  // namespace tessera::render
