// The eye-dome lighting pass (C. Boucheny, "Visualisation scientifique interactive de grands
// volumes de donnees: pour une approche perceptive", PhD thesis, Grenoble 2009, tel-00438464,
// pp. 115 ff.; in the form of Potree's src/materials/shaders/edl.fs), a screen pass on the
// resolved image: shade = exp(-300 k * mean over 8 neighbours of max(0, log2 d - log2 d_n)),
// d the linear view depth, k the strength; the image's colour is multiplied by it. Needs no
// normals, reads only depth, so it serves points and meshes alike. Two methods (EdlOptions):
//
// Classic (stage 2; Potree's form): raw depths, neighbours at uEdlRadius pixels, the sum divided
// by 8 whatever the number of neighbours with a point. On scans this speckles: range noise (0.2
// mm on the bunny scan, about one pixel footprint at 26 cm) gives each pixel the log depth of
// whichever noisy sample won it, so the shade changes with the LOD level (fewer, larger splats
// win) and with every small camera move.
//
// Robust (stage 0, then 1): stage 0 writes a denoised log depth per pixel, the value at the
// pixel centre of a least-squares plane fitted to the depths of its (2 uFilterRadius + 1)^2
// window: a depth plane over the splats, since Boucheny's shading is a function of the surface,
// not of the sample that wins a pixel. Only window pixels on the same surface take part: their
// log depth differs from the reference, the median of the 3x3 around the pixel, by at most
// uEdgeTau (1 + distance in pixels), uEdgeTau being log2(1 + s * pixel angle) for a surface
// slope s; so a depth step keeps its edge and its halo, and a lone sample of a layer behind
// (another scan seen through this one's gaps) takes the surface's depth instead of its own.
// With too few inliers for a plane (or a singular fit), their mean. A fitted plane keeps a
// slanted surface's depth where a mean over a one-sided window (at silhouettes) would shift it.
// Stage 1 shades from the denoised plane; the obscurance is normalised by the neighbours that
// have a point (not by 8), so a pixel on a silhouette shades like one inside whichever of its
// neighbours a level covers; the strength is divided by the radius, so a slope shades the same
// at any radius (a plane's response grows with the neighbour distance).
layout(local_size_x = 16, local_size_y = 16) in;

// The frame's depth and (stage 1) the denoised log depth, read as buffer textures: llvmpipe
// gathers texels with vector code, where it reads a storage buffer lane by lane.
layout(binding = TESSERA_TEXTURE_DEPTH) uniform usamplerBuffer uDepth;
layout(binding = TESSERA_TEXTURE_SCREEN_SCRATCH) uniform samplerBuffer uFiltered;
layout(std430, binding = TESSERA_BINDING_IMAGE) buffer Image { uint image[]; };
// Robust: the denoised log2 depth per pixel (stage 0), raster order, kNone where nothing was
// drawn.
layout(std430, binding = TESSERA_BINDING_SCREEN_SCRATCH) writeonly buffer Filtered {
  float filtered[];
};

// TESSERA_EDL_STAGE (EdlPass compiles one program per stage; a uniform's branches cost
// llvmpipe the untaken stages' work under a mask, 40 ms a pass at 1920x1080): robust 0 denoised
// log depth, 1 shade from it; 2: classic shade.
uniform ivec2 uSize;
uniform float uEdlStrength;
uniform int uEdlRadius;     // neighbour distance, pixels
uniform int uFilterRadius;  // stage 0 window half-width, pixels, <= TESSERA_EDL_MAX_FILTER_RADIUS
uniform float uEdgeTau;     // stage 0 same-surface bound, log2 depth per pixel of distance
uniform int uPlaneFit;      // stage 0: 1 fits a plane, 0 takes the inliers' mean
uniform int uMedian;        // stage 0: 1 judges inliers against the 3x3 median, 0 the pixel
uniform float uP22;         // projection[2][2] and [3][2]: linear depth from NDC depth
uniform float uP32;

const float kNone = -1e30;

uint depthAt(uint index) {
  return texelFetch(uDepth, int(index)).x;
}
const ivec2 kDirs[8] = ivec2[8](ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1),
                                ivec2(1, 1), ivec2(-1, -1), ivec2(1, -1), ivec2(-1, 1));

// log2 of the linear view depth of a depth-plane value that is not empty.
float logOf(uint d) {
  float ndc = uintBitsToFloat(d) * 2.0 - 1.0;
  return log2(max(uP32 / (ndc + uP22), 1e-30));
}

// The same, 0 where nothing was drawn (so a depth of exactly 1 m counts as empty: the classic
// form has always done so).
float logDepth(ivec2 q) {
  uint d = depthAt(uint(q.y) * uint(uSize.x) + uint(q.x));
  return d == 0xFFFFFFFFu ? 0.0 : logOf(d);
}

void shadeImage(ivec2 p, float shade) {
  uint out_index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
  uint rgba = image[out_index];
  vec3 c = vec3(rgba & 0xFFu, (rgba >> 8) & 0xFFu, (rgba >> 16) & 0xFFu) * shade;
  uvec3 u = uvec3(clamp(c + 0.5, 0.0, 255.0));
  image[out_index] = u.r | (u.g << 8) | (u.b << 16) | (rgba & 0xFF000000u);
}

void classic(ivec2 p) {
  float here = logDepth(p);
  float sum = 0.0;
  for (int k = 0; k < 8; ++k) {
    ivec2 q = clamp(p + kDirs[k] * uEdlRadius, ivec2(0), uSize - 1);
    float there = logDepth(q);
    if (there != 0.0) sum += max(0.0, here - there);
  }
  shadeImage(p, exp(-sum / 8.0 * 300.0 * uEdlStrength));
}

// Sorts a pair: a gets the smaller.
void order(inout float a, inout float b) {
  float lo = min(a, b);
  b = max(a, b);
  a = lo;
}

// The median of the window depths of the 3x3 pixels around covered pixel p, empty or outside
// ones standing in by the centre's `centre`: Paeth's 19-exchange network for 9 values (Graphics
// Gems, 1990). One sample of a layer behind (a scan registered a little off showing through the
// front one's gaps) or in front does not move it, so it cannot make its own window.
float median3x3(ivec2 p, float centre) {
  float v[9];
  for (int k = 0; k < 9; ++k) {
    ivec2 q = p + ivec2(k % 3 - 1, k / 3 - 1);
    bool inside = q.x >= 0 && q.y >= 0 && q.x < uSize.x && q.y < uSize.y;
    uint d = inside ? depthAt(uint(q.y) * uint(uSize.x) + uint(q.x)) : 0xFFFFFFFFu;
    v[k] = d == 0xFFFFFFFFu ? centre : uintBitsToFloat(d);
  }
  order(v[1], v[2]), order(v[4], v[5]), order(v[7], v[8]);
  order(v[0], v[1]), order(v[3], v[4]), order(v[6], v[7]);
  order(v[1], v[2]), order(v[4], v[5]), order(v[7], v[8]);
  order(v[0], v[3]), order(v[5], v[8]), order(v[4], v[7]);
  order(v[3], v[6]), order(v[1], v[4]), order(v[2], v[5]);
  order(v[4], v[7]), order(v[4], v[2]), order(v[6], v[4]);
  order(v[4], v[2]);
  return v[4];
}

// Stage 0: the denoised log depth of covered pixel p, depth plane value d. The plane is fitted
// to window depth, not log depth: window depth is affine in 1 / z, and 1 / z of a planar surface
// is affine in screen position, so a slanted plane fits exactly, and the taps need no logarithm
// (only the fitted centre does). Same surface means near the reference, the 3x3 median (or with
// uMedian 0 the pixel's own depth); the bound is turned into window depth there:
// d ln z = -(z / P32) d ndc, and ndc = 2 window depth - 1.
float denoise(ivec2 p, uint d) {
  int r = uFilterRadius;
  if (r == 0) return logOf(d);
  float centre = uMedian != 0 ? median3x3(p, uintBitsToFloat(d)) : uintBitsToFloat(d);
  float z = uP32 / (centre * 2.0 - 1.0 + uP22);
  float tau = uEdgeTau * log(2.0) * abs(uP32) / (2.0 * z);
  // Sums over the inliers at offsets (x, y) of 1, x, y, xx, xy, yy, v, xv, yv, with v the window
  // depth relative to the reference (exact in float, so the small differences keep their bits).
  float n = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, sxy = 0.0, syy = 0.0, sv = 0.0, sxv = 0.0,
        syv = 0.0;
  ivec2 lo = max(p - r, ivec2(0)) - p, hi = min(p + r, uSize - 1) - p;
  for (int dy = lo.y; dy <= hi.y; ++dy) {
    for (int dx = lo.x; dx <= hi.x; ++dx) {
      uint dq = depthAt(uint(p.y + dy) * uint(uSize.x) + uint(p.x + dx));
      if (dq == 0xFFFFFFFFu) continue;
      float v = uintBitsToFloat(dq) - centre;
      float x = float(dx), y = float(dy);
      if (abs(v) > tau * (1.0 + sqrt(x * x + y * y))) continue;
      n += 1.0;
      sx += x;
      sy += y;
      sxx += x * x;
      sxy += x * y;
      syy += y * y;
      sv += v;
      sxv += x * v;
      syv += y * v;
    }
  }
  float value = centre + sv / n;  // n >= 1: the reference is one of the window's depths
  if (uPlaneFit != 0 && n >= 6.0) {
    // v = a + b x + c y by least squares: the normal equations, a by Cramer's rule.
    float det =
        n * (sxx * syy - sxy * sxy) - sx * (sx * syy - sxy * sy) + sy * (sx * sxy - sxx * sy);
    if (abs(det) >= 1e-3 * n * n * n) {
      float det_a =
          sv * (sxx * syy - sxy * sxy) - sx * (sxv * syy - sxy * syv) + sy * (sxv * sxy - sxx * syv);
      value = centre + det_a / det;
    }
  }
  return logOf(floatBitsToUint(value));
}

void robustShade(ivec2 p) {
  float here = texelFetch(uFiltered, p.y * uSize.x + p.x).x;
  float sum = 0.0;
  int n = 0;
  for (int k = 0; k < 8; ++k) {
    ivec2 q = p + kDirs[k] * uEdlRadius;
    if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y) continue;
    float there = texelFetch(uFiltered, q.y * uSize.x + q.x).x;
    if (there == kNone) continue;
    sum += max(0.0, here - there);
    ++n;
  }
  if (n == 0) return;
  shadeImage(p, exp(-sum / float(n) * 300.0 * uEdlStrength / float(uEdlRadius)));
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint index = uint(p.y) * uint(uSize.x) + uint(p.x);
  uint d = depthAt(index);
#if TESSERA_EDL_STAGE == 0
  filtered[index] = d != 0xFFFFFFFFu ? denoise(p, d) : kNone;
#elif TESSERA_EDL_STAGE == 1
  if (d != 0xFFFFFFFFu) robustShade(p);
#else
  if (d != 0xFFFFFFFFu) classic(p);
#endif
}
