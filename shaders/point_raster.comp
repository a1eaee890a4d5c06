// Compute-shader point rasterisation (GL_POINTS draws ~5 M points/s on llvmpipe, a
// compute atomicMin scatter ~100 M points/s). Without 64-bit atomics the nearest point wins in
// two passes over the same points: pass 0 keeps the smallest depth per pixel (atomicMin on the
// depth's float bits, which order like the floats for depths in [0, 1]); pass 1, among points at
// that depth, keeps the smallest (position hash, colour) key and pick id, so the result is the
// same whatever the thread order and whichever buffer a point came from. Splats are round; their
// diameter follows the node's sample spacing as it projects at each point (uSpacingK / w
// pixels), times the point's own scale on leaves, so surfaces close at every LOD level without
// fat blobs behind near ones, radius capped at uRadius.
//
// Variants (render/src/point_pass.cpp compiles each, no run-time branch that llvmpipe
// would execute on both sides): PASS 0 or 1; ONE_PIXEL 1 when every splat of the dispatch is
// one pixel (far points, fine levels: no disc code at all).
#ifndef PASS
#define PASS 0
#endif
#ifndef ONE_PIXEL
#define ONE_PIXEL 0
#endif
layout(local_size_x = 128) in;

// struct Point: shaders/shared_layout.h
layout(binding = TESSERA_TEXTURE_POINTS) uniform usamplerBuffer uPointTexels;
// Point gi as RGBA32UI texel: position bits, rgba.
uvec4 pointAt(uint gi) {
  return texelFetch(uPointTexels, int(gi));
}
layout(std430, binding = TESSERA_BINDING_DEPTH) buffer Depth { uint depth[]; };
// The reads before the atomics (is this point nearer? is its footprint larger?) go through texel
// views of the same depth and footprint buffers (PointPass binds them): llvmpipe gathers a
// texture's texels with vector code where it reads a storage buffer lane by lane. Within a
// dispatch the two views are not coherent, so a read may return a value the atomics have since
// lowered (depth) or raised (footprints), never one that was not there: the read only decides
// whether to take the atomic, and a stale one only takes it where it was not needed, so the
// result is the same.
layout(binding = TESSERA_TEXTURE_DEPTH) uniform usamplerBuffer uDepthTexels;
layout(binding = TESSERA_TEXTURE_FOOTPRINTS) uniform usamplerBuffer uFootprintTexels;
uint depthAt(uint idx) {
  return texelFetch(uDepthTexels, int(idx)).x;
}
layout(std430, binding = TESSERA_BINDING_COLORS) buffer Colors { uint colors[]; };  // rgb, 0xFFFFFFFF: none
layout(std430, binding = TESSERA_BINDING_PICK) buffer Pick { uint pick[]; };  // frame-wide point id
layout(std430, binding = TESSERA_BINDING_COLOR_SUMS) buffer Sums { uint sums[]; };  // w r, w g, w b, w
// FILL: per pixel the footprint of the nearest point drawn on it (radius and position) and
// whether more than one point fell near it: two words a pixel.
layout(std430, binding = TESSERA_BINDING_SPLAT_FOOTPRINTS) buffer Footprints {
  uvec2 footprints[];
};

uniform mat4 uClip;            // clip from the batch's node frame
uniform uint uColorOverride;  // non-zero: 0x1000000 | rgb for every point of the batch
uniform int uWriteColor;      // pass 1 writes colours (0: one colour for all, only pick ids)
uniform uint uPickBase;       // pick id of this dispatch's first point
uniform float uBlendDepth;    // BLEND: the depth within which points add their colours (metres)
uniform float uP22;           // projection[2][2] and [3][2]: view depth from window depth
uniform float uP32;
uniform uint uFirst;    // first point of the batch in `points`
uniform uint uCount;
uniform ivec2 uSize;    // viewport in pixels
uniform int uRadius;    // the largest splat radius, pixels (the radius when uSpacingK is 0)
uniform float uSpacingK;  // node spacing in pixels at view depth 1 (0: fixed radius uRadius)
uniform float uOwnScaleCap;  // a point's top byte widens its disc up to this (1: the node's)
// The program's variant (PointPass compiles one per combination used, as it does for PASS,
// ONE_PIXEL and TESSERA_CLIPPING): a uniform's branches cost llvmpipe their work under a mask
// even where no lane takes them, an atomic a loop over the lanes (blending and pick ids compiled
// out took the RGB colour pass of 10^7 points from 83 to 63 ms).
// WRITE_PICK: pass 1 writes pick ids uPickBase + i. BLEND: pass 1 blends, every point within
// uBlendDepth of the nearest adding its colour, weighted by its splat's kernel, to sums[].
// FILL: 1 px points plus their splat footprints, for the pull-push fill (fill.comp).
const bool kWritePick = WRITE_PICK != 0;
const bool kBlend = BLEND != 0;
const bool kFill = FILL != 0;

// Pass 0 keeps the nearest depth; pass 1, among the points at that depth, one colour (below)
// and the smallest pick id (two points at exactly the same depth may give the colour of one and
// the id of the other: either is a nearest point). Blending instead (high-quality splatting, as
// Potree's: Botsch et al. 2005), pass 1 adds the colour of every point whose view depth w is
// within uBlendDepth of the nearest's, weighted by its splat kernel `k`, so the colours of the
// points that overlap on a surface average instead of the nearest one aliasing.
void write(uint idx, uint d, uint gi, uint i, float w, float k) {
#if PASS == 0
  // A read before the atomic: most points of a scan are behind the nearest (depth complexity),
  // and a read costs llvmpipe far less than an atomic.
  if (d > depthAt(idx)) return;
  atomicMin(depth[idx], d);
#else
  uint nearest = depthAt(idx);
  if (nearest != d && !kBlend) return;  // behind: most points, nothing more to read
  if (nearest == d && kWritePick) atomicMin(pick[idx], uPickBase + i);
  uint rgb = uColorOverride != 0u ? uColorOverride & 0xFFFFFFu : pointAt(gi).w & 0xFFFFFFu;
  if (kBlend) {
    // The nearest point always counts: far away, window depth's float steps exceed the
    // tolerance, and the view depth recovered from it may fall short of the point's own.
    float near_w = uP32 / ((uintBitsToFloat(nearest) * 2.0 - 1.0) + uP22);
    if (nearest != d && w > near_w + uBlendDepth) return;
    uint q = uint(clamp(k, 1.0 / 64.0, 1.0) * 255.0 + 0.5);
    atomicAdd(sums[idx * 4u], (rgb & 0xFFu) * q);
    atomicAdd(sums[idx * 4u + 1u], ((rgb >> 8) & 0xFFu) * q);
    atomicAdd(sums[idx * 4u + 2u], ((rgb >> 16) & 0xFFu) * q);
    atomicAdd(sums[idx * 4u + 3u], q);
  } else if (nearest == d && uWriteColor != 0) {
    // Ties (a surface facing the eye puts many points at one depth) go to the smallest of a
    // hash of the point's position in the top byte, then colour: an unbiased pick among the
    // tied points, the same in every process. The smallest colour alone would always pick the
    // darkest (a black-and-white plane came out black).
    uvec3 b = pointAt(gi).xyz;
    uint h = (b.x * 0x9E3779B1u) ^ (b.y * 0x85EBCA77u) ^ (b.z * 0xC2B2AE3Du);
    atomicMin(colors[idx], (h ^ (h >> 15)) << 24 | rgb);
  }
#endif
}

void raster(uint i) {
  uint gi = uFirst + i;
  uvec4 point = pointAt(gi);
  vec3 position = uintBitsToFloat(point.xyz);
  if (tesseraClipped(position)) return;  // cut away by a CLIP node
  vec4 c = uClip * vec4(position, 1.0);
  if (c.w <= 0.0) return;
  vec3 ndc = c.xyz / c.w;
  if (ndc.z < -1.0 || ndc.z > 1.0) return;
  vec2 pos = (ndc.xy * 0.5 + 0.5) * vec2(uSize);  // pixels, sub-pixel exact
  // Far off screen, or NaN (a bad position or transform): nothing to draw.
  vec2 margin = vec2(float(uRadius) + 2.0);
  if (!(all(greaterThan(pos, -margin)) && all(lessThan(pos, vec2(uSize) + margin)))) return;
  ivec2 centre = ivec2(floor(pos));
  uint d = floatBitsToUint(ndc.z * 0.5 + 0.5);
#if ONE_PIXEL
  if (centre.x < 0 || centre.y < 0 || centre.x >= uSize.x || centre.y >= uSize.y) return;
  write(uint(centre.y) * uint(uSize.x) + uint(centre.x), d, gi, i, c.w, 1.0);
#else
  // With a spacing, the splat is the disc of diameter (projected spacing) around the point's
  // exact position: it covers the pixels whose centres it contains, and always its own pixel.
  // Fixed splats cover the integer disc of radius uRadius around the point's pixel.
  // This is the one place a splat's size is decided: the discs below and the pull-push fill's
  // radii (FILL) both follow it. A leaf point's own scale (render/splat_sizes.h) widens its
  // disc to close the gaps of its sampling pattern (scan lines): 1 + top byte / 64. NaN (a bad
  // spacing) draws a single pixel.
  float scale = min(1.0 + float(point.w >> 24) / 64.0, uOwnScaleCap);
  float disc = uSpacingK > 0.0 ? min(0.5 * uSpacingK * scale / c.w, float(uRadius)) : 0.0;
  if (!(disc >= 0.0)) disc = 0.0;
  // A neighbour k pixels away has its centre at least k - 1/2 from the point: a disc of radius
  // up to 1/2 stays in the point's own pixel.
  int radius = uSpacingK > 0.0 ? int(ceil(disc - 0.5)) : max(uRadius, 0);
  bool on_screen = centre.x >= 0 && centre.y >= 0 && centre.x < uSize.x && centre.y < uSize.y;
  if (kFill && on_screen) {
    // Fill mode (Marroquim et al. 2007): the point as one pixel and the footprint its disc would
    // have had. Points off screen keep their discs: the fill has no samples beyond the viewport,
    // and their discs reach into it exactly as without the fill (the tiles of a wall meet as
    // before).
    uint idx = uint(centre.y) * uint(uSize.x) + uint(centre.x);
#if PASS == 0
    {
      // The footprint, packed as fill.comp reads it: the point's tesseraFillGroup() (so the
      // nearest point's wins), the radius in 1/16 pixels (bits 8-15, to 15.9) and the point's
      // position in its pixel in 1/16 pixels (x bits 4-7, y bits 0-3), so the fill tests reach
      // as the disc loop below does (a fixed disc is centred on its pixel). The largest print
      // wins: the nearest point's group, then within it the largest radius and position, whatever
      // order the points arrive in. The second word says that more than one point fell in that
      // nearest group (their other positions are lost): the largest group of a point that found
      // the pixel's nearest so far in its own group. Only a point whose group reaches that of
      // the nearest so far can be among the group: a read tells the others (in a volume of
      // points, most), and the atomic on the depth is taken only by a point nearer than what
      // the read saw. (Writing only for a point nearer than all before it, as the simpler variant did
      // session before last, left ties to the arrival order: 0.0742% or 0.0746% open pixels on
      // Autzen from run to run. Every point took the depth atomic and read the flag, and the
      // group was the top bits of the window depth itself, until the last session: 40-60% more
      // depth pass than the 1 px points, now 20-35%.)
      uint old = depthAt(idx);
      uint group = tesseraFillGroup(d);
      if (group < tesseraFillGroup(old)) return;
      if (d < old) old = atomicMin(depth[idx], d);
      uint old_group = tesseraFillGroup(old);
      if (group >= old_group) {
        uvec2 kept = texelFetch(uFootprintTexels, int(idx)).xy;
        float reach = uSpacingK > 0.0 ? disc : sqrt(float(radius * radius + radius));
        vec2 in_pixel = uSpacingK > 0.0 ? clamp(pos - vec2(centre), 0.0, 1.0) : vec2(0.5);
        uvec2 sub = uvec2(min(in_pixel * 16.0, vec2(15.0)));
        uint print = group | uint(min(reach * 16.0 + 0.5, 255.0)) << 8 | sub.x << 4 | sub.y;
        if (print > kept.x) atomicMax(footprints[idx].x, print);
        // The nearest so far in this point's group: more than one point in it.
        bool several = old != 0xFFFFFFFFu && group == old_group;
        if (several && group > kept.y) atomicMax(footprints[idx].y, group);
      }
      return;
    }
#else
    write(idx, d, gi, i, c.w, 1.0);
    return;
#endif
  }
  // Not compiled in fill mode, where every point on screen returned above and one off screen
  // has no pixel of its own: llvmpipe runs a branch's body under a mask even when no lane takes
  // it, and this one's read and atomic took the fill's depth pass 40-60% over the 1 px pass.
  if (!kFill && radius == 0) {
    // One pixel (fine LOD levels, far points): no loop, which llvmpipe runs much faster.
    if (centre.x < 0 || centre.y < 0 || centre.x >= uSize.x || centre.y >= uSize.y) return;
    uint idx = uint(centre.y) * uint(uSize.x) + uint(centre.x);
    write(idx, d, gi, i, c.w, 1.0);
    return;
  }
  int r2 = radius * radius + radius;
  for (int dy = -radius; dy <= radius; ++dy) {
    for (int dx = -radius; dx <= radius; ++dx) {
      if (uSpacingK > 0.0) {
        vec2 off = vec2(centre + ivec2(dx, dy)) + 0.5 - pos;
        if ((dx != 0 || dy != 0) && dot(off, off) > disc * disc) continue;
      } else if (dx * dx + dy * dy > r2) {
        continue;
      }
      ivec2 q = centre + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y) continue;
      uint idx = uint(q.y) * uint(uSize.x) + uint(q.x);
      // The splat kernel: 1 at the point, falling to 0 at the disc's edge.
      vec2 o = vec2(q) + 0.5 - pos;
      float r = uSpacingK > 0.0 ? disc : float(radius) + 0.5;
      write(idx, d, gi, i, c.w, 1.0 - dot(o, o) / (r * r));
    }
  }
#endif
}

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= uCount) return;
  raster(i);
}
