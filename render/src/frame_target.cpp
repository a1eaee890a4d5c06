#include <tessera/render/frame_target.h>

#include <string>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <tessera/core/check.h>
#include <tessera/render/gl_context.h>

namespace tessera::render {
namespace {

GlBuffer plane(uint32_t width, uint32_t height) {
  return GlBuffer(size_t(width) * height * 4, nullptr);
}

}  // namespace

FrameTarget::FrameTarget(uint32_t width, uint32_t height) : mWidth(width), mHeight(height) {
  // The screen passes read the planes as buffer textures (GlBufferTexture): at most 2^27 texels
  // in Mesa (GL_MAX_TEXTURE_BUFFER_SIZE), 11585x11585 or 16384x8192.
  if (width == 0 || height == 0 || width > 16384 || height > 16384 ||
      size_t(width) * height > kMaxFramePixels)
    throw RenderError("render::FrameTarget: a view of " + std::to_string(width) + "x" +
                      std::to_string(height) + " pixels (1..16384 each way, at most " +
                      std::to_string(kMaxFramePixels) + " pixels)");
  mDepth = plane(width, height);
  mColors = plane(width, height);
  mPick = plane(width, height);
  mImage = plane(width, height);
  mPick.clear(kNoPick);
}

const GlBuffer& FrameTarget::colorSums() {
  if (!mColorSums) mColorSums = GlBuffer(pixels() * 16, nullptr);
  return mColorSums;
}

const GlBuffer& FrameTarget::splatFootprints() {
  if (!mSplatFootprints) mSplatFootprints = GlBuffer(pixels() * 8, nullptr);
  return mSplatFootprints;
}

void FrameTarget::clearGeometry(bool pick, bool blend, bool footprints) {
  mDepth.clear(kEmptyDepth);
  mColors.clear(0xFFFFFFFFu);
  if (pick) mPick.clear(kNoPick);
  if (blend) {
    colorSums();
    mColorSums.clear(0);
  }
  if (footprints) {
    splatFootprints();
    mSplatFootprints.clear(0);
  }
}

Image readImageBuffer(const GlBuffer& plane, uint32_t width, uint32_t height) {
  Image img;
  img.width = width;
  img.height = height;
  img.rgba.resize(size_t(width) * height * 4);
  plane.read(0, img.rgba.size(), img.rgba.data());
  return img;
}

Image FrameTarget::readImage() const {
  return readImageBuffer(mImage, mWidth, mHeight);
}

void FrameTarget::copyImageRegion(uint32_t x, uint32_t y, uint32_t width, uint32_t height,
                                  const GlBuffer& out) const {
  TESSERA_CHECK(size_t(x) + width <= mWidth && size_t(y) + height <= mHeight &&
                    out.bytes() >= size_t(width) * height * 4,
                "render::FrameTarget::copyImageRegion(): region outside the image or the copy");
  for (uint32_t row = 0; row < height; ++row)
    glCopyNamedBufferSubData(mImage.name(), out.name(),
                             GLintptr((size_t(y + row) * mWidth + x) * 4),
                             GLintptr(size_t(row) * width * 4), GLsizeiptr(size_t(width) * 4));
}

std::vector<uint32_t> FrameTarget::readDepth() const {
  std::vector<uint32_t> v(pixels());
  mDepth.read(0, v.size() * 4, v.data());
  return v;
}

std::vector<uint32_t> FrameTarget::readPick() const {
  std::vector<uint32_t> v(pixels());
  mPick.read(0, v.size() * 4, v.data());
  return v;
}

uint32_t FrameTarget::readAt(const GlBuffer& plane, uint32_t x, uint32_t y) const {
  TESSERA_CHECK(x < mWidth && y < mHeight, "render::FrameTarget::readAt(): pixel outside");
  uint32_t v = 0;
  plane.read((size_t(mHeight - 1 - y) * mWidth + x) * 4, 4, &v);
  return v;
}

}  // namespace tessera::render
