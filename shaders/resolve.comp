// The resolve pass: each pixel's nearest colour (or its blended points' weighted mean, or the
// one colour of the frame, or the background where nothing was drawn) into the image, rows flipped so row 0 is the top.
// MODE (ResolvePass compiles one program each: no uniform branch that llvmpipe would
// run under a mask for every pixel): 0 the nearest colour, 1 the blended points' weighted mean,
// 2 one colour for the frame (no colour pass ran). The planes are read as texels of buffer views
// (ResolvePass binds them): llvmpipe gathers texels with vector code where it reads a storage
// buffer lane by lane. Branch-free: every pixel reads its depth and colour and writes one word.
layout(local_size_x = 16, local_size_y = 16) in;

layout(binding = TESSERA_TEXTURE_DEPTH) uniform usamplerBuffer uDepthTexels;
layout(binding = TESSERA_TEXTURE_COLORS) uniform usamplerBuffer uColorTexels;  // rgb of the winner
layout(binding = TESSERA_TEXTURE_COLOR_SUMS) uniform usamplerBuffer uSumTexels;  // r, g, b, weight
layout(std430, binding = TESSERA_BINDING_IMAGE) writeonly buffer Image { uint image[]; };

uniform ivec2 uSize;
uniform uint uBackground;    // rgba, r in the low byte
uniform uint uUniformColor;  // MODE 2: every point has this colour

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  int pixel = p.y * uSize.x + p.x;
  uint out_index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
  uint d = texelFetch(uDepthTexels, pixel).x;
#if MODE == 1
  uvec4 s = texelFetch(uSumTexels, pixel);
  uvec3 c = (s.rgb + s.a / 2u) / max(s.a, 1u);
  uint rgb = c.r | (c.g << 8) | (c.b << 16);
#elif MODE == 2
  uint rgb = uUniformColor;
#else
  // colors[] holds a tie-break key in its top byte (point_raster.comp).
  uint rgb = texelFetch(uColorTexels, pixel).x & 0xFFFFFFu;
#endif
  image[out_index] = d == 0xFFFFFFFFu ? uBackground : rgb | 0xFF000000u;
}
