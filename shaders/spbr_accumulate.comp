// Stochastic point-based rendering, step 3 (Tanaka et al. 2016, section 3.1): adds the images
// of the ensembles just drawn (uLayers depth/colour layers; background where no point won) into
// integer sums per pixel, so averaging is exact and independent of order. uMode 1 instead
// divides the sums by the number of ensembles accumulated and writes the image (rows flipped so
// row 0 is the top). Accumulating also keeps the nearest copy's depth in the frame target, for
// the passes that test against the scene (overlays).
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = TESSERA_BINDING_DEPTH) readonly buffer Depth { uint depth[]; };
layout(std430, binding = TESSERA_BINDING_COLORS) readonly buffer Colors { uint colors[]; };
layout(std430, binding = TESSERA_BINDING_IMAGE) writeonly buffer Image { uint image[]; };
layout(std430, binding = TESSERA_BINDING_ACCUM) buffer Accum { uint accum[]; };  // r, g, b sums per pixel
layout(std430, binding = TESSERA_BINDING_TARGET_DEPTH) buffer Target { uint target_depth[]; };

uniform ivec2 uSize;
uniform uint uLayers;
uniform uint uBackground;    // rgba, r in the low byte
uniform uint uUniformColor;  // non-zero: every point has this colour (no colour layers)
uniform int uMode;           // 0: accumulate, 1: resolve
uniform uint uAccumulated;   // ensembles in the sums (resolve)

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint pixel = uint(p.y) * uint(uSize.x) + uint(p.x);
  if (uMode == 1) {
    uvec3 sum = uvec3(accum[pixel * 3u], accum[pixel * 3u + 1u], accum[pixel * 3u + 2u]);
    uvec3 v = (sum + uAccumulated / 2u) / max(uAccumulated, 1u);
    uint out_index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
    image[out_index] = v.r | (v.g << 8) | (v.b << 16) | 0xFF000000u;
    return;
  }
  uint plane = uint(uSize.x) * uint(uSize.y);
  uvec3 sum = uvec3(0u);
  uint nearest = target_depth[pixel];
  for (uint l = 0u; l < uLayers; ++l) {
    uint k = l * plane + pixel;
    nearest = min(nearest, depth[k]);
    uint c = depth[k] == 0xFFFFFFFFu ? uBackground
                                     : (uUniformColor != 0u ? uUniformColor : colors[k]);
    sum += uvec3(c & 0xFFu, (c >> 8) & 0xFFu, (c >> 16) & 0xFFu);
  }
  accum[pixel * 3u] += sum.r;
  accum[pixel * 3u + 1u] += sum.g;
  accum[pixel * 3u + 2u] += sum.b;
  target_depth[pixel] = nearest;
}
