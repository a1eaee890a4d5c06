// The projector pass (render/projector_pass.h): each projector pixel shows the rendered image
// where it lands on the screen (the warp grid, bilinear), times its blend weight through the
// projector's gamma. The rendered image is RGBA8 words, top row first; so is the output.
layout(local_size_x = 16, local_size_y = 16) in;

layout(binding = 2) uniform usamplerBuffer uSource;  // the rendered image
layout(binding = 3) uniform samplerBuffer uBlend;    // weight per projector pixel (linear light)
layout(binding = 4) uniform samplerBuffer uWarp;     // (u, v) per grid vertex, top row first
layout(std430, binding = 3) writeonly buffer Projected { uint projected[]; };

uniform ivec2 uSize;      // projector pixels
uniform ivec2 uGrid;      // warp vertices (0: no warp)
uniform int uBlendOn;     // 1: uBlend holds the weights
uniform float uInvGamma;  // 1 / the projector's gamma

vec4 texel(ivec2 p) {
  return unpackUnorm4x8(texelFetch(uSource, p.y * uSize.x + p.x).r);
}

vec2 vertex(int i, int j) {
  return texelFetch(uWarp, j * uGrid.x + i).rg;
}

void main() {
  const ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
  if (pixel.x >= uSize.x || pixel.y >= uSize.y) return;
  const uint index = uint(pixel.y * uSize.x + pixel.x);
  vec3 rgb;
  if (uGrid.x == 0) {
    rgb = texel(pixel).rgb;
  } else {
    // Where the pixel lands: the grid cell holding its centre, bilinear.
    const vec2 st = (vec2(pixel) + 0.5) / vec2(uSize);
    const vec2 g = st * vec2(uGrid - 1);
    const ivec2 c = min(ivec2(floor(g)), uGrid - 2);
    const vec2 f = g - vec2(c);
    const vec2 uv = mix(mix(vertex(c.x, c.y), vertex(c.x + 1, c.y), f.x),
                        mix(vertex(c.x, c.y + 1), vertex(c.x + 1, c.y + 1), f.x), f.y);
    if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) {
      rgb = vec3(0.0);
    } else {
      // The rendered image there, bilinear between pixel centres, clamped at its edges.
      const vec2 p = uv * vec2(uSize) - 0.5;
      const ivec2 p0 = ivec2(floor(p));
      const vec2 t = p - vec2(p0);
      const ivec2 lo = clamp(p0, ivec2(0), uSize - 1), hi = clamp(p0 + 1, ivec2(0), uSize - 1);
      rgb = mix(mix(texel(lo).rgb, texel(ivec2(hi.x, lo.y)).rgb, t.x),
                mix(texel(ivec2(lo.x, hi.y)).rgb, texel(hi).rgb, t.x), t.y);
    }
  }
  if (uBlendOn != 0) rgb *= pow(max(texelFetch(uBlend, int(index)).r, 0.0), uInvGamma);
  projected[index] = packUnorm4x8(vec4(rgb, 1.0));
}
