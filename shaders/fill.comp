// The pull-push surface fill (R. Marroquim, M. Kraus, P. R. Cavalcanti, "Efficient point-based
// rendering using image reconstruction", Eurographics Symposium on Point-Based Graphics 2007):
// points are drawn as single pixels (point_raster.comp with uFill), each pixel also keeping the
// footprint its splat's disc would have had (radius and sub-pixel position); this pass closes
// the surface between them in screen space, at a cost proportional to the pixels instead of the
// splats' area.
//
// Samples: every texel of every level holds one sample as a uvec2 (kEmpty in .y: none): .x its
// view depth (half float, low 16 bits), its radius (1/16 px, bits 16-23) and its point's position
// in its pixel (1/16 px, x bits 24-27, y bits 28-31); .y its level-0 pixel, y << 16 | x, from
// which the winner's depth, colour and pick id are read. Two words a candidate, since llvmpipe
// reads buffers lane by lane and the reads are the cost. Where several points fell on a pixel
// (point_raster.comp flags it) the sample sits at the pixel's centre with the nearest point's
// radius grown by half the pixel's diagonal: a disc that holds the others' too where their radii
// are alike (points of one LOD node).
//
// Stages (TESSERA_FILL_STAGE, one program each):
// Pull (1, levels 1 .. uLevels - 1; level 1 first packs level 0's samples from the frame
// target's depth and footprints): each texel of level l keeps one sample of its 2x2
// finer texels: of those on the front surface (within the depth tolerance of the nearest:
// Marroquim's depth test, so a back surface seen through the front's holes does not climb the
// pyramid), the one whose disc holds the texel's centre deepest.
// Push (2 for levels uLevels .. 1, then 3 for the pixels): coarse to fine, as the paper's push
// phase. A texel of level l >= 1 takes the best of the level l - 1 samples under it and a ring of
// one around them (4x4) and of the winners of the 3x3 level l + 1 texels around its parent, which
// carry what reaches from further away; a pixel the best of the samples of its 2x2 block and the
// ring around it and of the winners of its block's level-1 texel and the 8 around. Where the paper
// interpolates coarser texels into every empty pixel and limits the fill by each sample's projected
// ellipse, here a sample counts only where its disc reaches (the disc rule of point_raster.comp:
// the pixel centre lies within the splat's radius of the point; above level 0, any part of the
// texel), so silhouettes grow no further than the discs would and background stays background.
// Among the samples that reach, the front surface wins (one nearer by more than the depth tolerance
// replaces the one kept), and on that surface the one whose disc holds the centre deepest (the
// lowest power distance, squared distance minus squared radius). A pixel keeps its own sample
// unless it has none or the winner lies in front of it by more than the tolerance (a back surface
// seen through a hole of the front, which the front's disc would cover). The result goes to the
// pass's own planes, so no invocation reads another's output.
//
// Depth tolerance: uTolerance splat radii at the sample's view depth (the radius in pixels times
// the world size of a pixel there), at least one pixel's worth: the depth change across a disc of
// a surface sloped up to atan(uTolerance) from the view plane.
layout(local_size_x = 16, local_size_y = 16) in;

// The frame's planes, read as buffer textures (FillPass binds views of them): depth, colours,
// pick ids, and per pixel the footprint of its nearest point (point_raster.comp): the top 16
// bits of its inverted depth, its radius in 1/16 pixels (bits 8-15), its position in the pixel
// in 1/16 pixels (x bits 4-7, y bits 0-3); then non-zero when more than one point fell on it.
layout(binding = TESSERA_TEXTURE_DEPTH) uniform usamplerBuffer uDepth;
layout(binding = TESSERA_TEXTURE_COLORS) uniform usamplerBuffer uColors;
layout(binding = TESSERA_TEXTURE_PICK) uniform usamplerBuffer uPick;
layout(binding = TESSERA_TEXTURE_FOOTPRINTS) uniform usamplerBuffer uFootprints;
// The pyramid as two RG32UI textures with mip levels (FillPass): the samples, level l at mip l,
// and the push's winners, level l at mip l - 1. Read with texelFetch, written with imageStore to
// one mip level: llvmpipe gathers texels with vector code, where it reads a buffer lane by lane
// (a 4x4 and a 3x3 read: 8 ms against 18 ms a pass over 960x540 texels on this machine).
layout(binding = TESSERA_TEXTURE_FILL_SAMPLES) uniform usampler2D uSamples;
layout(binding = TESSERA_TEXTURE_FILL_WINNERS) uniform usampler2D uWinnerTexels;
// The level written (stage 1: the samples of uLevel; 2: the winners of uLevel), and in stage 1
// at level 1 the level-0 samples packed on the way.
layout(rg32ui, binding = TESSERA_IMAGE_FILL_OUT) uniform writeonly uimage2D uOut;
layout(rg32ui, binding = TESSERA_IMAGE_FILL_LEVEL0) uniform writeonly uimage2D uLevel0;
layout(std430, binding = TESSERA_BINDING_FILL_DEPTH) writeonly buffer OutDepth { uint out_depth[]; };
layout(std430, binding = TESSERA_BINDING_FILL_COLORS) writeonly buffer OutColors { uint out_colors[]; };
layout(std430, binding = TESSERA_BINDING_FILL_PICK) writeonly buffer OutPick { uint out_pick[]; };

uniform int uLevel;        // pull and push of a level: the level written, 1..uLevels
uniform int uLevels;       // coarsest level, <= TESSERA_FILL_MAX_LEVELS
uniform ivec2 uSize;       // level 0 (the frame target) in pixels
uniform float uMaxRadius;  // radii above are clamped to it (pixels)
uniform float uTolerance;  // depth tolerance in splat radii
uniform float uPixelK;     // world size of a pixel at view depth 1 (2 / (P11 height))
uniform float uP22;        // projection[2][2] and [3][2]: view depth from window depth
uniform float uP32;
uniform int uWriteColor;   // copy colours of the winners
uniform int uWritePick;    // copy pick ids of the winners

const uint kEmpty = 0xFFFFFFFFu;

ivec2 levelSize(int l) {
  return (uSize + ivec2((1 << l) - 1)) >> l;
}

uint idOf(ivec2 p) {
  return uint(p.y) << 16 | uint(p.x);
}

uint indexOf(uint id) {
  return (id >> 16) * uint(uSize.x) + (id & 0xFFFFu);
}

float viewDepth(uint d) {
  return uP32 / ((uintBitsToFloat(d) * 2.0 - 1.0) + uP22);
}

// Texel q of level l, of the samples or (`winners`) of the push's winners; none outside.
uvec2 texel(int l, ivec2 q, bool winners) {
  ivec2 size = levelSize(l);
  if (q.x < 0 || q.y < 0 || q.x >= size.x || q.y >= size.y) return uvec2(0u, kEmpty);
  return winners ? texelFetch(uWinnerTexels, q, l - 1).xy : texelFetch(uSamples, q, l).xy;
}

// A sample unpacked: view depth, radius, the point's position (pixels) and the depth tolerance
// of its surface (view depth units).
struct Sample {
  float w, r;
  vec2 pos;
  float tol;
};

Sample unpack(uvec2 s) {
  vec2 sub = (vec2((s.x >> 24) & 0xFu, s.x >> 28) + 0.5) / 16.0;
  float w = unpackHalf2x16(s.x).x, r = float((s.x >> 16) & 0xFFu) / 16.0;
  return Sample(w, r, vec2(float(s.y & 0xFFFFu), float(s.y >> 16)) + sub,
                uTolerance * max(r, 1.0) * w * uPixelK);
}

// The sample kept so far for one pixel or texel.
struct Winner {
  uvec2 s;      // packed, .y kEmpty: none
  float w;      // view depth
  float tol;    // depth tolerance of its surface, view depth units
  float power;  // squared distance to the centre minus squared reach: the lower the deeper
};

Winner noWinner() {
  return Winner(uvec2(0u, kEmpty), 0.0, 0.0, 0.0);
}

// Takes sample `s` (packed `cand`) into `best` if its disc reaches within `slack` pixels of `at`
// and it lies on the front surface: nearer than the kept one by more than the tolerance, or on
// the same surface holding `at` deeper (lower power distance, then the smaller id, so the
// result does not depend on the candidates' order). Without branches: llvmpipe runs every path
// of a branch its lanes disagree on anyway.
void consider(inout Winner best, vec2 at, float slack, uvec2 cand, Sample s) {
  vec2 off = at - s.pos;
  float reach = s.r + slack;
  float power = dot(off, off) - reach * reach;
  bool none = best.s.y == kEmpty;
  bool front = s.w < best.w - best.tol;
  bool same = s.w <= best.w + best.tol;
  bool deeper = power < best.power || (power == best.power && cand.y < best.s.y);
  bool take = cand.y != kEmpty && power <= 0.0 && (none || front || (same && deeper));
  if (take) best = Winner(cand, s.w, s.tol, power);
}

// Level 0's sample of pixel p (none outside the frame).
uvec2 packPixel(ivec2 p) {
  if (p.x >= uSize.x || p.y >= uSize.y) return uvec2(0u, kEmpty);
  uint pixel = uint(p.y) * uint(uSize.x) + uint(p.x);
  uint d = texelFetch(uDepth, int(pixel)).x;
  uvec2 print = texelFetch(uFootprints, int(pixel)).xy;
  uint f = print.x;
  // The footprint is the nearest point's unless that was a disc from off screen (no footprint).
  bool nearest = d != kEmpty && (f >> 16) == (~d >> 16);
  float r = nearest ? min(float((f >> 8) & 0xFFu) / 16.0, uMaxRadius) : 0.0;
  bool several = print.y != 0u;
  uvec2 sub = several ? uvec2(8u) : uvec2((f >> 4) & 0xFu, f & 0xFu);
  if (several && r > 0.0) r += 0.70711;
  uint r8 = uint(min(r * 16.0 + 0.5, 255.0));  // to 1/32 px of the disc's
  uvec2 s = uvec2(0u, kEmpty);
  if (r8 > 0u)
    s = uvec2((packHalf2x16(vec2(viewDepth(d), 0.0)) & 0xFFFFu) | r8 << 16 | sub.x << 24 |
                  sub.y << 28,
              idOf(p));
  imageStore(uLevel0, p, uvec4(s, 0u, 0u));
  return s;
}

float frontOf(uvec2 c) {
  return c.y == kEmpty ? 1e30 : unpackHalf2x16(c.x).x;
}

// Pull: child `c` competes for the texel's centre if it lies on the front surface.
void pullChild(inout Winner best, float front, vec2 centre, uvec2 c) {
  if (c.y == kEmpty) return;
  Sample s = unpack(c);
  vec2 off = centre - s.pos;
  float power = dot(off, off) - s.r * s.r;
  bool deeper = power < best.power || (power == best.power && c.y < best.s.y);
  if (s.w <= front + s.tol && (best.s.y == kEmpty || deeper)) best = Winner(c, s.w, 0.0, power);
}

// Pull level uLevel; level 1 packs level 0's samples on the way (stage 0: one invocation per
// 2x2 pixels, so the frame's planes are read once).
void pull() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = levelSize(uLevel);
  if (t.x >= size.x || t.y >= size.y) return;
  ivec2 b = 2 * t;
  uvec2 c0, c1, c2, c3;
  if (uLevel == 1) {
    c0 = packPixel(b);
    c1 = packPixel(b + ivec2(1, 0));
    c2 = packPixel(b + ivec2(0, 1));
    c3 = packPixel(b + ivec2(1));
  } else {
    c0 = texel(uLevel - 1, b, false);
    c1 = texel(uLevel - 1, b + ivec2(1, 0), false);
    c2 = texel(uLevel - 1, b + ivec2(0, 1), false);
    c3 = texel(uLevel - 1, b + ivec2(1), false);
  }
  float front = min(min(frontOf(c0), frontOf(c1)), min(frontOf(c2), frontOf(c3)));
  // The front surface's children compete as in the push, for the texel's centre.
  Winner best = noWinner();
  vec2 centre = (vec2(t) + 0.5) * float(1 << uLevel);
  pullChild(best, front, centre, c0);
  pullChild(best, front, centre, c1);
  pullChild(best, front, centre, c2);
  pullChild(best, front, centre, c3);
  imageStore(uOut, t, uvec4(best.s, 0u, 0u));
}

// Push, a level >= 1: the best of the level l - 1 samples under texel t and a ring of one
// (4x4), and of the winners of the 3x3 level l + 1 texels around its parent.
void pushLevel() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = levelSize(uLevel);
  if (t.x >= size.x || t.y >= size.y) return;
  float scale = float(1 << uLevel);
  vec2 at = (vec2(t) + 0.5) * scale;
  float slack = 0.70711 * scale;
  Winner best = noWinner();
  // Nothing reaches t when the coarser winners around its parent are all empty (see push()).
  bool top = uLevel == uLevels, any = top;
  for (int k = 0; k < 9 && !top; ++k)
    any = any || texel(uLevel + 1, (t >> 1) + ivec2(k % 3, k / 3) - 1, true).y != kEmpty;
  for (int k = any ? 0 : 16; k < 16; ++k) {
    uvec2 c = texel(uLevel - 1, 2 * t + ivec2(k & 3, k >> 2) - 1, false);
    consider(best, at, slack, c, unpack(c));
  }
  for (int k = any && !top ? 0 : 9; k < 9; ++k) {
    uvec2 c = texel(uLevel + 1, (t >> 1) + ivec2(k % 3, k / 3) - 1, true);
    consider(best, at, slack, c, unpack(c));
  }
  imageStore(uOut, t, uvec4(best.s, 0u, 0u));
}

// The four pixels of the 2x2 block at `base` consider candidate `c` (four variables, not an
// array: llvmpipe keeps an indexed array in memory, lane by lane). A pixel's own sample is a
// candidate too: on the front surface it holds its pixel deepest and stays.
void considerBlock(inout Winner b0, inout Winner b1, inout Winner b2, inout Winner b3, ivec2 base,
                   uvec2 c) {
  if (c.y == kEmpty) return;
  Sample s = unpack(c);
  vec2 at = vec2(base) + 0.5;
  consider(b0, at, 0.0, c, s);
  consider(b1, at + vec2(1.0, 0.0), 0.0, c, s);
  consider(b2, at + vec2(0.0, 1.0), 0.0, c, s);
  consider(b3, at + vec2(1.0), 0.0, c, s);
}

// A pixel's result: its own sample unless it has none or `best` lies in front of it by more
// than the tolerance.
void resolvePixel(ivec2 p, Winner best) {
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint pixel = uint(p.y) * uint(uSize.x) + uint(p.x);
  uint own = texelFetch(uDepth, int(pixel)).x;
  uint src = pixel;
  if (best.s.y != kEmpty && (own == kEmpty || viewDepth(own) > best.w + best.tol))
    src = indexOf(best.s.y);
  uint d = src == pixel ? own : texelFetch(uDepth, int(src)).x;
  out_depth[pixel] = d;
  if (uWriteColor != 0) out_colors[pixel] = d == kEmpty ? kEmpty : texelFetch(uColors, int(src)).x;
  if (uWritePick != 0) out_pick[pixel] = d == kEmpty ? kEmpty : texelFetch(uPick, int(src)).x;
}

// Push, the pixels: one invocation per 2x2 block (a level-1 texel), so each candidate is read
// and unpacked once for the four: the level-0 samples of the block and a ring of one (4x4), and
// the winners of the block's level-1 texel and its 8 neighbours.
// Skipped where nothing can reach: each level-0 sample of the 4x4 lies in one of those 9 level-1
// texels and reaches it (a sample reaches any texel it lies in: the slack is the texel's half
// diagonal), so when all 9 winners are empty so are the samples, and the block is background.
// pushLevel() skips likewise from the winners around its parent. The candidates are read in
// loops with a per-invocation start rather than branches: llvmpipe runs both sides of a branch
// its lanes disagree on under a mask, but leaves a loop as soon as no lane is in it (on the 10^7
// point cube at 1920x1080 this pass went from 55 to 29 ms, the pixels unchanged).
void push() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = levelSize(1);
  if (t.x >= size.x || t.y >= size.y) return;
  ivec2 base = 2 * t;
  Winner b0 = noWinner(), b1 = noWinner(), b2 = noWinner(), b3 = noWinner();
  bool any = false;
  for (int k = 0; k < 9; ++k) any = any || texel(1, t + ivec2(k % 3, k / 3) - 1, true).y != kEmpty;
  for (int k = any ? 0 : 16; k < 16; ++k)
    considerBlock(b0, b1, b2, b3, base, texel(0, base + ivec2(k & 3, k >> 2) - 1, false));
  for (int k = any ? 0 : 9; k < 9; ++k)
    considerBlock(b0, b1, b2, b3, base, texel(1, t + ivec2(k % 3, k / 3) - 1, true));
  resolvePixel(base, b0);
  resolvePixel(base + ivec2(1, 0), b1);
  resolvePixel(base + ivec2(0, 1), b2);
  resolvePixel(base + ivec2(1), b3);
}

// Each stage is its own program (FillPass defines TESSERA_FILL_STAGE), so each compiles to just
// its own code.
void main() {
#if TESSERA_FILL_STAGE == 1
  pull();
#elif TESSERA_FILL_STAGE == 2
  pushLevel();
#else
  push();
#endif
}
