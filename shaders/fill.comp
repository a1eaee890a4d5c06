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
// in the nearest's depth group (tesseraFillGroup() in shared_layout.h, 1.6-3.2% of the view
// depth) the sample sits at the pixel's centre with the largest of their radii grown by half the
// pixel's diagonal: a disc that holds the others' too where their radii are alike (points of
// one LOD node).
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
//
// Tiles: the pass works only where a sample can reach. Stage 0 marks the tiles of
// TESSERA_FILL_TILE pixels that hold a drawn pixel; FillPass reads the marks back, grows them by
// the farthest reach (a sample's radius plus the coarsest texel's half diagonal, so no winner of
// any level lies outside) and lists those tiles together with last frame's (which this frame
// empties); every other stage runs over the listed tiles only, an invocation per texel of its
// level. Texels of unlisted tiles hold kEmpty at every level (FillPass clears the pyramid when
// it is made or its levels change, and a tile leaving the list is emptied by the frame that
// lists it last), and their pixels keep the frame's own values: no disc reaches them.
#if TESSERA_FILL_STAGE == 0
layout(local_size_x = 8, local_size_y = 8) in;
#else
layout(local_size_x = 64) in;
#endif

// The frame's planes, read as buffer textures (FillPass binds views of them): depth, colours,
// pick ids, and per pixel the footprint of its nearest point (point_raster.comp): its depth
// group (top 14 bits), its radius in 1/16 pixels (bits 8-15), its position in the pixel in 1/16
// pixels (x bits 4-7, y bits 0-3); then the same group where more than one point fell in it.
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
// Stage 0: a word per tile, set where the tile holds a drawn pixel. Stage 4: the frame's planes,
// written back from the pass's own (then bound to uDepth, uColors, uPick) in the listed tiles.
layout(std430, binding = TESSERA_BINDING_FILL_TILE_MARKS) writeonly buffer TileMarks {
  uint tile_marks[];
};
layout(std430, binding = TESSERA_BINDING_DEPTH) writeonly buffer FrameDepth { uint frame_depth[]; };
layout(std430, binding = TESSERA_BINDING_COLORS) writeonly buffer FrameColors {
  uint frame_colors[];
};
layout(std430, binding = TESSERA_BINDING_PICK) writeonly buffer FramePick { uint frame_pick[]; };
// The listed tiles, y << 16 | x each.
layout(binding = TESSERA_TEXTURE_FILL_TILES) uniform usamplerBuffer uTiles;

uniform int uLevel;        // pull and push of a level: the level written, 1..uLevels
uniform int uLevels;       // coarsest level, <= TESSERA_FILL_MAX_LEVELS
uniform ivec2 uSize;       // level 0 (the frame target) in pixels
uniform float uMaxRadius;  // radii above are clamped to it (pixels)
uniform float uTolerance;  // depth tolerance in splat radii
uniform float uPixelK;     // world size of a pixel at view depth 1 (2 / (P11 height))
uniform float uP22;        // projection[2][2] and [3][2]: view depth from window depth
uniform float uP32;
// WRITE_COLOR, WRITE_PICK (defines, FillPass compiles a program per combination): copy the
// colours, the pick ids of the winners.
const bool kWriteColor = WRITE_COLOR != 0;
const bool kWritePick = WRITE_PICK != 0;
uniform int uTileCount;    // tiles listed
uniform int uTileShift;    // log2 of a tile's side in this stage's texels (2x2 blocks: 3)

const uint kEmpty = 0xFFFFFFFFu;
// In the pass's depth plane: the pixel keeps the frame's own values (no window depth has these
// bits).
const uint kKeep = 0xFFFFFFFEu;

ivec2 levelSize(int l) {
  return (uSize + ivec2((1 << l) - 1)) >> l;
}

// The texel of this invocation: invocations run over the listed tiles, 4^uTileShift each, x
// fastest. (-1, -1) past the list.
ivec2 tiledTexel() {
  uint g = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * gl_WorkGroupSize.x +
           gl_LocalInvocationIndex;
  uint tile = g >> (2 * uTileShift);
  if (tile >= uint(uTileCount)) return ivec2(-1);
  uint id = texelFetch(uTiles, int(tile)).x;
  uint side = 1u << uTileShift, local = g & (side * side - 1u);
  return (ivec2(id & 0xFFFFu, id >> 16) << uTileShift) +
         ivec2(local & (side - 1u), local >> uTileShift);
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

// The push's winners of the 3x3 texels of level l around q, read once (nine variables, not an
// array: llvmpipe keeps an indexed array in memory and reads it lane by lane), and whether any
// is not empty. None read when `skip`.
struct Around3x3 {
  uvec2 c0, c1, c2, c3, c4, c5, c6, c7, c8;
  bool any;
};

uvec2 aroundAt(Around3x3 a, int k) {
  return k < 4 ? (k < 2 ? (k == 0 ? a.c0 : a.c1) : (k == 2 ? a.c2 : a.c3))
               : (k < 6 ? (k == 4 ? a.c4 : a.c5) : (k < 8 ? (k == 6 ? a.c6 : a.c7) : a.c8));
}

Around3x3 around(int l, ivec2 q, bool skip) {
  Around3x3 a;
  a.c0 = a.c1 = a.c2 = a.c3 = a.c4 = a.c5 = a.c6 = a.c7 = a.c8 = uvec2(0u, kEmpty);
  for (int k = skip ? 9 : 0; k < 9; ++k) {
    uvec2 c = texel(l, q + ivec2(k % 3, k / 3) - 1, true);
    if (k == 0) a.c0 = c; if (k == 1) a.c1 = c; if (k == 2) a.c2 = c;
    if (k == 3) a.c3 = c; if (k == 4) a.c4 = c; if (k == 5) a.c5 = c;
    if (k == 6) a.c6 = c; if (k == 7) a.c7 = c; if (k == 8) a.c8 = c;
  }
  a.any =
      (a.c0.y & a.c1.y & a.c2.y & a.c3.y & a.c4.y & a.c5.y & a.c6.y & a.c7.y & a.c8.y) != kEmpty;
  return a;
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
  uint group = tesseraFillGroup(d);
  bool nearest = d != kEmpty && (f & 0xFFFF0000u) == group;
  float r = nearest ? min(float((f >> 8) & 0xFFu) / 16.0, uMaxRadius) : 0.0;
  bool several = print.y != 0u && print.y == group;
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

// Pull level uLevel; level 1 packs level 0's samples on the way (one invocation per 2x2 pixels,
// so the frame's planes are read once).
void pull() {
  ivec2 t = tiledTexel();
  ivec2 size = levelSize(uLevel);
  if (t.x < 0 || t.x >= size.x || t.y >= size.y) return;
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
  ivec2 t = tiledTexel();
  ivec2 size = levelSize(uLevel);
  if (t.x < 0 || t.x >= size.x || t.y >= size.y) return;
  float scale = float(1 << uLevel);
  vec2 at = (vec2(t) + 0.5) * scale;
  float slack = 0.70711 * scale;
  Winner best = noWinner();
  // Nothing reaches t when the coarser winners around its parent are all empty (see push()).
  bool top = uLevel == uLevels;
  Around3x3 w = around(uLevel + 1, t >> 1, top);
  bool any = top || w.any;
  for (int k = any ? 0 : 16; k < 16; ++k) {
    uvec2 c = texel(uLevel - 1, 2 * t + ivec2(k & 3, k >> 2) - 1, false);
    consider(best, at, slack, c, unpack(c));
  }
  for (int k = any && !top ? 0 : 9; k < 9; ++k) {
    uvec2 c = aroundAt(w, k);
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
  // Most pixels keep their own values: one word says so, and the colour and pick id are read
  // and written in a loop only the lanes of changed pixels enter (llvmpipe runs a branch's body
  // under a mask for every lane, but leaves a loop no lane is in).
  bool keep = src == pixel;
  uint d = keep ? own : texelFetch(uDepth, int(src)).x;
  out_depth[pixel] = keep ? kKeep : d;
  for (int k = keep ? 1 : 0; k < 1; ++k) {
    if (kWriteColor) out_colors[pixel] = d == kEmpty ? kEmpty : texelFetch(uColors, int(src)).x;
    if (kWritePick) out_pick[pixel] = d == kEmpty ? kEmpty : texelFetch(uPick, int(src)).x;
  }
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
  ivec2 t = tiledTexel();
  ivec2 size = levelSize(1);
  if (t.x < 0 || t.x >= size.x || t.y >= size.y) return;
  ivec2 base = 2 * t;
  Winner b0 = noWinner(), b1 = noWinner(), b2 = noWinner(), b3 = noWinner();
  Around3x3 w = around(1, t, false);
  for (int k = w.any ? 0 : 16; k < 16; ++k)
    considerBlock(b0, b1, b2, b3, base, texel(0, base + ivec2(k & 3, k >> 2) - 1, false));
  for (int k = w.any ? 0 : 9; k < 9; ++k) considerBlock(b0, b1, b2, b3, base, aroundAt(w, k));
  resolvePixel(base, b0);
  resolvePixel(base + ivec2(1, 0), b1);
  resolvePixel(base + ivec2(0, 1), b2);
  resolvePixel(base + ivec2(1), b3);
}

// Stage 0: marks the tile of each 2x2 block that holds a drawn pixel (an 8x8 group a tile).
void mark() {
  ivec2 b = 2 * ivec2(gl_GlobalInvocationID.xy);
  bool any = false;
  for (int k = 0; k < 4; ++k) {
    ivec2 p = b + ivec2(k & 1, k >> 1);
    bool inside = p.x < uSize.x && p.y < uSize.y;
    any = any || (inside && texelFetch(uDepth, p.y * uSize.x + p.x).x != kEmpty);
  }
  int tiles_x = (uSize.x + TESSERA_FILL_TILE - 1) / TESSERA_FILL_TILE;
  if (any) tile_marks[(b.y / TESSERA_FILL_TILE) * tiles_x + b.x / TESSERA_FILL_TILE] = 1u;
}

// Stage 4: the pass's planes (bound to uDepth, uColors, uPick) back into the frame's where the
// fill changed a pixel, a pixel an invocation over the listed tiles.
void writeBack() {
  ivec2 p = tiledTexel();
  if (p.x < 0 || p.x >= uSize.x || p.y >= uSize.y) return;
  int pixel = p.y * uSize.x + p.x;
  uint d = texelFetch(uDepth, pixel).x;
  for (int k = d == kKeep ? 1 : 0; k < 1; ++k) {  // only pixels the fill changed
    frame_depth[pixel] = d;
    if (kWriteColor) frame_colors[pixel] = texelFetch(uColors, pixel).x;
    if (kWritePick) frame_pick[pixel] = texelFetch(uPick, pixel).x;
  }
}

// Each stage is its own program (FillPass defines TESSERA_FILL_STAGE), so each compiles to just
// its own code.
void main() {
#if TESSERA_FILL_STAGE == 0
  mark();
#elif TESSERA_FILL_STAGE == 1
  pull();
#elif TESSERA_FILL_STAGE == 2
  pushLevel();
#elif TESSERA_FILL_STAGE == 3
  push();
#else
  writeBack();
#endif
}
