// The foveal inset's weights (render/inset.h InsetPass): each pixel of a context tile or an
// inset's slot times its weight in linear light (gamma 2.2), as applySlotWeights() does on the
// CPU; an inset's border drawn just inside its band. The picture is RGBA8 words, top row first;
// so is the output.
layout(local_size_x = 16, local_size_y = 16) in;

layout(binding = 2) uniform usamplerBuffer uSource;  // the rendered picture
layout(std430, binding = 3) writeonly buffer Weighted { uint weighted[]; };

uniform ivec2 uSize;       // pixels
uniform vec2 uPixel;       // metres a pixel on the wall plane, x and y
uniform int uCount;        // insets in uRects
// Each inset's rectangle (x0, y0, x1, y1), metres from the picture's top-left corner (y up, so
// rows below the corner are negative), and its band, metres.
uniform vec4 uRects[64];
uniform float uBands[64];
uniform int uInset;        // 1: an inset's slot (uRects[0] is its rectangle); 0: a context tile
uniform float uBorder;     // an inset's frame, pixels (0: none)
uniform vec2 uBandPixels;  // an inset's band in its pixels, x and y

float contextWeight(int i, vec2 p) {
  const vec4 r = uRects[i];
  const float d = min(min(p.x - r.x, r.z - p.x), min(p.y - r.y, r.w - p.y));
  if (d <= 0.0) return 1.0;
  if (uBands[i] <= 0.0 || d >= uBands[i]) return 0.0;
  return 1.0 - d / uBands[i];
}

void main() {
  const ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
  if (pixel.x >= uSize.x || pixel.y >= uSize.y) return;
  const int index = pixel.y * uSize.x + pixel.x;
  vec4 c = unpackUnorm4x8(texelFetch(uSource, index).r);
  const vec2 p = vec2((float(pixel.x) + 0.5) * uPixel.x, -(float(pixel.y) + 0.5) * uPixel.y);
  float w = 1.0;
  if (uInset != 0) {
    if (uBorder > 0.0) {
      const vec2 e = min(vec2(pixel) + 0.5, vec2(uSize) - vec2(pixel) - 0.5) - uBandPixels;
      const float d = min(e.x, e.y);
      if (d >= 0.0 && d < uBorder) {
        weighted[index] = packUnorm4x8(vec4(vec3(200.0 / 255.0), c.a));
        return;
      }
    }
    const vec4 r = uRects[0];
    const bool inside = p.x > r.x && p.x < r.z && p.y > r.y && p.y < r.w;
    w = inside ? 1.0 - contextWeight(0, p) : 0.0;
  } else {
    for (int i = 0; i < uCount; ++i) w *= contextWeight(i, p);
  }
  if (w < 1.0) c.rgb = w <= 0.0 ? vec3(0.0) : pow(w * pow(c.rgb, vec3(2.2)), vec3(1.0 / 2.2));
  weighted[index] = packUnorm4x8(c);
}
