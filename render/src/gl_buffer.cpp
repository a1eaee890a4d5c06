#include <tessera/render/gl_buffer.h>

#include <algorithm>
#include <cstring>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

namespace tessera::render {

GlBuffer::GlBuffer(size_t bytes, const void* data, uint32_t flags)
    : mBytes(std::max<size_t>(bytes, 16)) {
  // GL refuses empty storage; tiny contents are padded so the driver never reads past `data`.
  unsigned char padded[16] = {};
  if (data && bytes < 16) {
    std::memcpy(padded, data, bytes);
    data = padded;
  }
  glCreateBuffers(1, &mName);
  glNamedBufferStorage(mName, GLsizeiptr(mBytes), data, flags);
}

GlBuffer::~GlBuffer() {
  if (mName) glDeleteBuffers(1, &mName);
}

void GlBuffer::clear(uint32_t word) {
  glClearNamedBufferData(mName, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &word);
}

void GlBuffer::read(size_t offset, size_t bytes, void* out) const {
  glGetNamedBufferSubData(mName, GLintptr(offset), GLsizeiptr(bytes), out);
}

}  // namespace tessera::render
