// Stochastic point-based rendering (Tanaka et al. 2016, section 3): each point of a node is
// thinned or copied by the node's adjustment ratio k (eq. 4; floor(k) copies plus one more with
// probability frac(k)), copy c of point i going to ensemble (h(i) + c) mod L, h a stable hash of
// the node key and the point's index: tiles and runs agree, copies of one point land in distinct
// ensembles, and no point is invented. This dispatch draws ensembles [uGroupFirst, uGroupFirst +
// uGroupCount) into as many depth (and colour) layers, each with an ordinary depth test: pass 0
// keeps the nearest depth, pass 1 the smallest colour at that depth (deterministic). A point's
// cross-section s is a disc facing the viewer (so slanted surfaces gather more points per pixel:
// eq. 2's shading); it covers the pixels whose centres it contains, so its expected coverage is
// exactly its projected area even below one pixel, which is what eq. 1 counts.
//
// Sparse scans (2 to 8 points a pixel; the paper assumes ~38), where the copies of a point would
// fill most ensembles alike and the L images average to binary noise:
// - IN_CELL (SpbrCopies::kInCell, the default): copy c of point i lands uniformly in the
//   rectangle of the point's surface cell (spbr.h surfaceCells(): its Voronoi cell in the tangent
//   plane, by area moments), at the c-th point of an R2 sequence (Roberts 2018) shifted by a hash
//   of h(i): the copies of one point are stratified over its cell across the ensembles, the
//   number of copies follows the cell's area, so every ensemble is an even cover of the surface
//   and the copies never leave the point's cell (edges stay within a spacing).
// - uJitterK > 0 (SpbrCopies::kGaussian): copy c moves in the image plane by a Gaussian offset
//   of uJitterK / w pixels from a hash of (h(i), c); with HAS_CELLS, copies are centred on the
//   cell's centroid and their number scaled by the cell's area.
// Eq. 1 then holds per ensemble for a cover of the surface rather than for one frozen sample of
// it (with a correction for the cover's regularity, view_renderer.cpp).
//
// Variants (PointPass compiles one per combination used: llvmpipe runs a uniform's
// branch under a mask even where no lane takes it, so the Gaussian copies' logarithm, sine and
// cosine cost the default in-cell copies their time while they were switched by uniforms): PASS
// 0 (depth) or 1 (colour); HAS_CELLS (cells[] centre and weigh each point's copies); IN_CELL
// (copies stratified over the cell's rectangle, needs HAS_CELLS); JITTER (Gaussian copies,
// uJitterK > 0, without IN_CELL); SLANT_OFF (cross-section s cos(theta) / cos(phi), from the
// point's normal); HAS_RATIOS (k scaled by each point's density ratio, for density jumps in a
// node); ONE_LAYER (every ensemble into layer 0: one opaque pass, a speed baseline).
// The per-point inputs are read as texels of buffer views (PointPass binds them): llvmpipe
// gathers a texture's texels with vector code where it reads a storage buffer lane by lane.
layout(local_size_x = 128) in;

// struct Point: shaders/shared_layout.h, as an RGBA32UI texel (position bits, rgba).
layout(binding = TESSERA_TEXTURE_POINTS) uniform usamplerBuffer uPointTexels;
layout(binding = TESSERA_TEXTURE_SPBR_NORMALS) uniform usamplerBuffer uNormals;  // 10:10:10 snorm
layout(binding = TESSERA_TEXTURE_SPBR_RATIOS) uniform samplerBuffer uRatios;  // node / local density
layout(binding = TESSERA_TEXTURE_SPBR_CELLS) uniform usamplerBuffer uCells;   // packCell()
// The colour pass's read of the depth a layer kept (final after the depth pass).
layout(binding = TESSERA_TEXTURE_DEPTH) uniform usamplerBuffer uDepthTexels;
layout(std430, binding = TESSERA_BINDING_DEPTH) buffer Depth { uint depth[]; };    // uGroupCount layers
layout(std430, binding = TESSERA_BINDING_COLORS) buffer Colors { uint colors[]; };  // uGroupCount layers

uniform mat4 uClip;
uniform uint uColorOverride;  // non-zero: 0x1000000 | rgb for every point of the batch
uniform uint uFirst;          // the batch's first point (texel) and its inputs', this slice's
uniform uint uCount;
uniform ivec2 uSize;
uniform float uDiscK;     // disc radius in pixels at view depth 1
uniform float uK;         // copies per point over all uTotal ensembles, <= uCopyCap
uniform uint uCopyCap;    // most copies of one point (uTotal)
uniform float uJitterK;   // copies' offset standard deviation, pixels at view depth 1 (0: none)
uniform float uCellUnit;  // store units of the cells' axes
uniform float uEnsembleShift;  // IN_CELL: pixels over which whole ensembles shift (1: a pixel)
uniform float uCellSpread;  // IN_CELL: how far copies spread over their cells (spbrCellSpread())
uniform uint uTotal;      // L
uniform uint uGroupFirst;
uniform uint uGroupCount;
uniform uint uSeed;       // stable key of the node
uniform int uMaxRadius;
uniform vec3 uEyeLocal;   // the eye in the batch's frame (for theta, SLANT_OFF)

uint hash(uint x) {  // lowbias32 (C. Wellons)
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

void splat(uint layer, vec2 pos, ivec2 centre, float r, uint d, uint rgb) {
  int reach = min(int(floor(r + 0.5)), uMaxRadius);
  uint base = ONE_LAYER != 0 ? 0u : layer * uint(uSize.x) * uint(uSize.y);
  for (int dy = -reach; dy <= reach; ++dy) {
    for (int dx = -reach; dx <= reach; ++dx) {
      ivec2 q = centre + ivec2(dx, dy);
      vec2 off = vec2(q) + 0.5 - pos;
      if (dot(off, off) > r * r) continue;
      if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y) continue;
      uint idx = base + uint(q.y) * uint(uSize.x) + uint(q.x);
#if PASS == 0
      atomicMin(depth[idx], d);
#else
      if (texelFetch(uDepthTexels, int(idx)).x == d) atomicMin(colors[idx], rgb);
#endif
    }
  }
}

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= uCount) return;
  uint h = hash(uSeed ^ hash(i + 0x9e3779b9u));
  int gi = int(uFirst + i);
  float k = HAS_RATIOS != 0 ? uK * texelFetch(uRatios, gi).x : uK;
  uvec4 point = texelFetch(uPointTexels, gi);
  vec3 position = uintBitsToFloat(point.xyz);
  if (tesseraClipped(position)) return;  // cut away by a CLIP node (its copies with it)
  vec3 axis_u = vec3(0.0), axis_v = vec3(0.0);
#if HAS_CELLS
  {
    uvec4 cell = texelFetch(uCells, gi);
    vec2 a = unpackHalf2x16(cell.x), b = unpackHalf2x16(cell.y), e = unpackHalf2x16(cell.z);
    axis_u = vec3(a, b.x) * uCellUnit;
    axis_v = vec3(b.y, e) * uCellUnit;
    vec2 centre = unpackSnorm4x8(cell.w).zw * 4.0;  // the centroid in the rectangle's frame
    float weight = unpackHalf2x16(cell.w).x;
    if (IN_CELL != 0) {
      // Part way (uCellSpread < 1): the rectangle, the centroid and the weight scaled towards
      // the paper's copies at the point.
      centre *= uCellSpread;
      weight = 1.0 + (weight - 1.0) * uCellSpread;
      axis_u *= uCellSpread;
      axis_v *= uCellSpread;
    }
    position += centre.x * axis_u + centre.y * axis_v;
    k *= weight;
  }
#endif
  // A large cell may ask for more copies than ensembles: the disc grows to keep its area.
  float grow = k > float(uCopyCap) ? sqrt(k / float(uCopyCap)) : 1.0;
  k = min(k, float(uCopyCap));
  float whole = floor(k);
  float u = float(hash(h ^ 0x85ebca6bu) >> 8) * (1.0 / 16777216.0);
  uint copies = min(uint(whole) + (u < k - whole ? 1u : 0u), uCopyCap);
  if (copies == 0u) return;
  // Copy c sits in ensemble (e0 + c) mod L; this dispatch draws [uGroupFirst, + uGroupCount).
  uint e0 = h % uTotal;
  uint a = (uGroupFirst + uTotal - e0) % uTotal;  // copy index of uGroupFirst
  bool any = copies >= uTotal || a < copies || a + uGroupCount > uTotal;
  if (!any) return;

  vec4 c = uClip * vec4(position, 1.0);
  if (c.w <= 0.0) return;
  vec3 ndc = c.xyz / c.w;
  if (ndc.z < -1.0 || ndc.z > 1.0) return;
  vec2 pos = (ndc.xy * 0.5 + 0.5) * vec2(uSize);
  uint d = floatBitsToUint(ndc.z * 0.5 + 0.5);
  float r = grow * uDiscK / c.w;
#if SLANT_OFF
  {
    // Cancel eq. 2's gain. A disc here is a circle of radius uDiscK / w on the screen (w the
    // depth along the view axis), so a surface element's points per pixel, against a surface
    // parallel to the image at the same depth, scale as cos(phi) / cos(theta): theta between
    // its normal and the ray, phi between the ray and the view axis (eq. 2's 1 / cos(theta) on
    // the axis). The cross-section s cos(theta) / cos(phi) keeps the opacity at alpha everywhere
    // in the view. cos(theta) / cos(phi) = |n . (p - eye)| |grad w| / w: the gradient of w is the
    // clip matrix's last row, and w is 0 at the eye. An orthographic view (w constant) has
    // phi = 0 and theta the angle to its axis. A point without a normal (0) faces the viewer.
    uint bits = texelFetch(uNormals, gi).x;
    vec3 n = vec3(float(int(bits << 22) >> 22), float(int(bits << 12) >> 22),
                  float(int(bits << 2) >> 22)) / 511.0;
    float n2 = dot(n, n);
    if (n2 > 0.25) {
      n *= inversesqrt(n2);
      vec3 grad_w = vec3(uClip[0][3], uClip[1][3], uClip[2][3]);
      float ratio = dot(grad_w, grad_w) > 0.0
                        ? abs(dot(n, position - uEyeLocal)) * length(grad_w) / c.w
                        : abs(dot(n, normalize(vec3(uClip[0][2], uClip[1][2], uClip[2][2]))));
      r *= sqrt(clamp(ratio, 0.02, 50.0));
    }
  }
#endif
  uint rgb = uColorOverride != 0u ? uColorOverride & 0xFFFFFFu : point.w & 0xFFFFFFu;
  float sigma = uJitterK / c.w;
  // The cell's rectangle on the screen (affine: a cell is a fraction of a pixel to a few).
  vec2 du = vec2(0.0), dv = vec2(0.0);
  vec2 r2 = vec2(0.0);
  if (IN_CELL != 0) {
    vec4 cu = uClip * vec4(position + axis_u, 1.0), cv = uClip * vec4(position + axis_v, 1.0);
    du = (cu.xy / cu.w - ndc.xy) * 0.5 * vec2(uSize);
    dv = (cv.xy / cv.w - ndc.xy) * 0.5 * vec2(uSize);
    // The R2 sequence's start, per point (Cranley-Patterson rotation).
    r2 = vec2(float(hash(h ^ 0x3c6ef372u) >> 8), float(hash(h ^ 0xa54ff53au) >> 8)) *
         (1.0 / 16777216.0);
  }
  for (uint cc = 0u; cc < copies; ++cc) {
    uint layer = (e0 + cc) % uTotal + uTotal - uGroupFirst;  // ensemble - uGroupFirst, mod L
    layer %= uTotal;
    if (layer >= uGroupCount) continue;
    vec2 p = pos;
    if (IN_CELL != 0) {
      // Copy cc at the cc-th point of R2 (1 / phi2, 1 / phi2^2), phi2 the plastic number.
      vec2 q = fract(r2 + float(cc) * vec2(0.7548776662, 0.5698402910)) * 2.0 - 1.0;
      p += q.x * du + q.y * dv;
      // The whole ensemble shifted within the pixel (its index on R2): the average samples each
      // pixel at L places, a box filter over what remains of the cover's own structure.
      uint ensemble = (e0 + cc) % uTotal;
      uint se = hash(ensemble * 0x9e3779b9u + 0x7f4a7c15u);
      p += (vec2(float(se >> 16), float(se & 0xFFFFu)) * (1.0 / 65536.0) - 0.5) * uCellSpread *
           uEnsembleShift;
    } else if (JITTER != 0 && sigma > 0.0) {
      // Box-Muller from the copy's own hash: the same offset in both passes and on every tile.
      uint g = hash(h ^ hash(cc * 0x27d4eb2fu + 0x165667b1u));
      float u1 = (float(g >> 8) + 0.5) * (1.0 / 16777216.0);
      float u2 = float(hash(g ^ 0x68e31da4u) >> 8) * (1.0 / 16777216.0);
      float rho = sigma * sqrt(-2.0 * log(u1));
      p += rho * vec2(cos(6.2831853 * u2), sin(6.2831853 * u2));
    }
    splat(layer, p, ivec2(floor(p)), r, d, rgb);
  }
}
