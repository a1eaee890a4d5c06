// Analysis filters of the Atelier3D framework (L. Borgeat, G. Godin, F. Blais, J.-A. Beraldin,
// P. Massicotte, G. Poirier, "Visualizing and analyzing large and detailed 3D datasets",
// section 4), screen passes on the resolved image that read only the frame's depth, so they
// serve points and meshes alike:
//
// Relative depth (stages 0-2): the linear view depth d, a large Gaussian blur of it G*d (two
// separable passes; sigma = uRadius / 3, empty pixels carry no weight, so a silhouette does not
// pull the blur towards the background), the difference d - G*d, which keeps the fine relief and
// drops the global shape, its range over the frame by a parallel reduction (atomic min and max
// of order-preserving float bits), then a perceptual colour map (viridis) over that range, or
// over a range given (a wall agrees on one). Silhouettes and tree crowns give a few differences
// far larger than the relief, so the frame's range is its 1st to 99th percentile: stage 1 finds
// the extremes, stage 4 a histogram of kBins bins between them, whose percentiles the pass reads
// back. Stage 0: horizontal weighted sums into a plane of (sum w d, sum w); stage 1: vertical
// sums, the difference into a float plane and its extremes; stage 4: the histogram; stage 2:
// the colour map, mixed into the image by uAmount.
//
// Contour lines (stages 3 and 5): a value per pixel, the linear view depth or the height along a
// world axis (reconstructed from the pixel's depth through the inverse projection), averaged
// over the pixel's 5x5 window on the same surface (stage 3: points drawn as discs give each
// pixel the depth of whichever sample won it; the mean is the surface's), then cut into levels
// floor(value / interval + phase); a pixel is on a line where a 4-neighbour on the same surface
// lies on a higher level (stage 5), so every crossing of a level marks exactly one pixel,
// however flat the surface (the paper's one-pixel rule), and a depth step marks nothing.
layout(local_size_x = 16, local_size_y = 16) in;

layout(binding = TESSERA_TEXTURE_DEPTH) uniform usamplerBuffer uDepth;
layout(binding = TESSERA_TEXTURE_SCREEN_SCRATCH) uniform samplerBuffer uScratch;
layout(std430, binding = TESSERA_BINDING_IMAGE) buffer Image { uint image[]; };
layout(std430, binding = TESSERA_BINDING_SCREEN_SCRATCH) buffer Sums { vec2 sums[]; };
layout(std430, binding = TESSERA_BINDING_ANALYSIS_PLANE) buffer Plane { float plane[]; };
layout(std430, binding = TESSERA_BINDING_ANALYSIS_RANGE) buffer Range { uint range[]; };
// range[0], range[1]: the extremes as ordered float bits; range[2 ..]: the histogram.

uniform ivec2 uSize;
uniform float uP22;  // projection[2][2] and [3][2]: linear depth from NDC depth
uniform float uP32;
// Relative depth.
uniform int uRadius;      // blur half-width, pixels
uniform float uAmount;    // 1: the colour map replaces the image; 0: nothing
uniform int uFixedRange;  // 1: uRangeLo..uRangeHi; 0: this frame's own range
uniform float uRangeLo;
uniform float uRangeHi;
// Contour lines.
uniform mat4 uViewFromClip;  // inverse projection: a pixel's view-space position
uniform int uHeight;         // 1: height along uAxis (view space); 0: view depth
uniform vec3 uAxis;
uniform float uInvInterval;  // lines per unit of the value
uniform float uPhase;        // levels: floor(value * uInvInterval + uPhase)
uniform float uEdge;         // same surface: neighbours' view depths within this fraction
uniform vec4 uLineColor;     // rgb 0..1 and opacity

const uint kEmpty = 0xFFFFFFFFu;

uint depthBits(ivec2 q) {
  return texelFetch(uDepth, q.y * uSize.x + q.x).x;
}

float linearDepth(uint bits) {
  float ndc = uintBitsToFloat(bits) * 2.0 - 1.0;
  return uP32 / (ndc + uP22);
}

// The picture's own pixels, without its guard band: only they set the relative depth's range.
uniform ivec4 uInner;  // x0, y0, x1, y1 (exclusive), raster order

bool inner(ivec2 p) {
  return all(greaterThanEqual(p, uInner.xy)) && all(lessThan(p, uInner.zw));
}

uint imageIndex(ivec2 p) {
  return uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
}

void mixImage(ivec2 p, vec3 rgb, float a) {
  uint index = imageIndex(p);
  uint rgba = image[index];
  vec3 c = vec3(rgba & 0xFFu, (rgba >> 8) & 0xFFu, (rgba >> 16) & 0xFFu);
  uvec3 u = uvec3(clamp(mix(c, rgb * 255.0, a) + 0.5, 0.0, 255.0));
  image[index] = u.r | (u.g << 8) | (u.b << 16) | (rgba & 0xFF000000u);
}

// Floats as unsigned integers in the same order (atomicMin and atomicMax over them).
uint orderedBits(float f) {
  uint b = floatBitsToUint(f);
  return (b & 0x80000000u) != 0u ? ~b : b | 0x80000000u;
}

float rangeValue(uint u) {
  return uintBitsToFloat((u & 0x80000000u) != 0u ? u & 0x7FFFFFFFu : ~u);
}

// Taps every stride() pixels: a blur wider than 6 pixels keeps 13 taps a pass (its sigma,
// radius / 3, stays at least twice the stride, where a sampled Gaussian still sums evenly). The
// taps' weights come from AnalysisPass (uWeights[i]: the i-th tap from the left), counted along
// the loop: no exp and no integer division a tap (llvmpipe has no vector division).
int stride() {
  return max(1, uRadius / 6);
}

uniform float uWeights[TESSERA_ANALYSIS_MAX_TAPS];


// Viridis (van der Walt and Smith, matplotlib) at nine stops, linear between them.
vec3 viridis(float t) {
  const vec3 stops[9] = vec3[9](vec3(68, 1, 84), vec3(72, 40, 120), vec3(62, 74, 137),
                                vec3(49, 104, 142), vec3(38, 130, 142), vec3(31, 158, 137),
                                vec3(53, 183, 121), vec3(109, 205, 89), vec3(253, 231, 37));
  float x = clamp(t, 0.0, 1.0) * 8.0;
  int i = min(int(x), 7);
  return mix(stops[i], stops[i + 1], x - float(i)) / 255.0;
}

float contourValue(ivec2 q, uint bits) {
  if (uHeight == 0) return linearDepth(bits);
  vec2 ndc = (vec2(q) + 0.5) / vec2(uSize) * 2.0 - 1.0;
  vec4 v = uViewFromClip * vec4(ndc, uintBitsToFloat(bits) * 2.0 - 1.0, 1.0);
  return dot(uAxis, v.xyz / v.w);
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint index = uint(p.y) * uint(uSize.x) + uint(p.x);
#if TESSERA_ANALYSIS_STAGE == 0
  vec2 s = vec2(0.0);
  int step = stride(), i = 0;
  for (int k = -(uRadius / step) * step; k <= uRadius; k += step, ++i) {
    int x = p.x + k;
    if (x < 0 || x >= uSize.x) continue;
    uint b = depthBits(ivec2(x, p.y));
    if (b == kEmpty) continue;
    float w = uWeights[i];
    s += vec2(w * linearDepth(b), w);
  }
  sums[index] = s;
#elif TESSERA_ANALYSIS_STAGE == 1
  uint b = depthBits(p);
  if (b == kEmpty) return;
  vec2 s = vec2(0.0);
  int step = stride(), i = 0;
  for (int k = -(uRadius / step) * step; k <= uRadius; k += step, ++i) {
    int y = p.y + k;
    if (y < 0 || y >= uSize.y) continue;
    s += uWeights[i] * texelFetch(uScratch, y * uSize.x + p.x).xy;
  }
  float relative = linearDepth(b) - s.x / s.y;
  plane[index] = relative;
  // The extremes of the pixels the histogram takes (every other one each way): a quarter of
  // the atomics on these two words, which llvmpipe's threads contend for.
  if (((p.x | p.y) & 1) == 0 && inner(p)) {
    atomicMin(range[0], orderedBits(relative));
    atomicMax(range[1], orderedBits(relative));
  }
#elif TESSERA_ANALYSIS_STAGE == 2
  if (depthBits(p) == kEmpty) return;
  float lo = uRangeLo, hi = uRangeHi;
  if (uFixedRange == 0) {
    lo = rangeValue(range[0]);
    hi = rangeValue(range[1]);
  }
  float t = hi > lo ? (texelFetch(uScratch, int(index)).x - lo) / (hi - lo) : 0.5;
  mixImage(p, viridis(t), uAmount);
#elif TESSERA_ANALYSIS_STAGE == 4
  // Every other pixel each way: a quarter of the atomics, percentiles of 500,000 samples at
  // 1920x1080 (their error far below a bin).
  if (((p.x | p.y) & 1) != 0 || depthBits(p) == kEmpty || !inner(p)) return;
  float lo = rangeValue(range[0]), hi = rangeValue(range[1]);
  if (!(hi > lo)) return;
  float t = (texelFetch(uScratch, int(index)).x - lo) / (hi - lo);
  atomicAdd(range[2 + min(uint(t * float(TESSERA_ANALYSIS_BINS)), TESSERA_ANALYSIS_BINS - 1u)], 1u);
#elif TESSERA_ANALYSIS_STAGE == 3
  uint b = depthBits(p);
  if (b == kEmpty) return;
  float d = linearDepth(b);
  float sum = 0.0, n = 0.0;
  for (int dy = -2; dy <= 2; ++dy) {
    for (int dx = -2; dx <= 2; ++dx) {
      ivec2 q = p + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y) continue;
      uint bq = depthBits(q);
      if (bq == kEmpty || abs(linearDepth(bq) - d) > uEdge * d * max(abs(dx), abs(dy))) continue;
      sum += contourValue(q, bq);
      n += 1.0;
    }
  }
  plane[index] = sum / n;
#else
  uint b = depthBits(p);
  if (b == kEmpty) return;
  float d = linearDepth(b);
  float level = floor(texelFetch(uScratch, int(index)).x * uInvInterval + uPhase);
  const ivec2 kNeighbours[4] = ivec2[4](ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1));
  for (int i = 0; i < 4; ++i) {
    ivec2 q = p + kNeighbours[i];
    if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y) continue;
    uint bq = depthBits(q);
    if (bq == kEmpty || abs(linearDepth(bq) - d) > uEdge * d) continue;
    int iq = q.y * uSize.x + q.x;
    if (floor(texelFetch(uScratch, iq).x * uInvInterval + uPhase) > level) {
      mixImage(p, uLineColor.rgb, uLineColor.a);
      return;
    }
  }
#endif
}
