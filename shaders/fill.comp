// The pull-push surface fill (R. Marroquim, M. Kraus, P. R. Cavalcanti, "Efficient point-based
// rendering using image reconstruction", Eurographics Symposium on Point-Based Graphics 2007,
// sections 4-5): points are drawn as single pixels (point_raster.comp with uFill), each pixel
// also keeping the radius in pixels its splat's disc would have had; this pass closes the
// surface between them in screen space, at a cost proportional to the pixels instead of the
// splats' area.
//
// Pull (uStage 0, once per level 1..uLevels): each texel of level l keeps one sample of its 2x2
// finer texels, the nearest in depth (Marroquim's depth test: the front surface wins, so a back
// surface seen through the front's holes does not climb the pyramid). A texel is a uvec2:
// window depth bits (kEmpty where no child has a sample) and the level-0 pixel index of the
// sample, from which its colour, pick id, radius and position are read. Level 0 is the frame
// target itself.
//
// Push (uStage 1, once over the pixels): where the paper interpolates coarser texels into every
// empty pixel and limits the fill by each sample's projected ellipse, here each pixel gathers the
// samples of its 3x3 neighbours at level 0 and of its 3x3 neighbourhood at every level up to
// uLevels (reach 2^uLevels pixels, at least the largest radius), and keeps only those whose disc
// reaches it: |pixel - sample pixel| <= the sample's radius, the discs' own coverage rule, so
// silhouettes grow no further than the discs would and background stays background. Among them
// the front surface wins (a candidate nearer by more than the depth tolerance replaces the one
// kept), and on that surface the sample nearest on screen (a Voronoi fill, sharper than the
// disc overlap's depth order). A pixel that has its own sample keeps it unless the winner lies
// in front of it by more than the tolerance: then the pixel is occluded (a back surface seen
// through a hole of the front) and takes the front sample, as the front's disc would cover it.
// The result goes to separate planes (the pass's own), so no invocation reads another's output.
//
// Depth tolerance: uTolerance splat radii at the sample's view depth (the radius in pixels times
// the world size of a pixel there), at least one pixel's worth: the depth change across a disc of
// a surface sloped up to atan(uTolerance) from the view plane.
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = TESSERA_BINDING_DEPTH) readonly buffer Depth { uint depth[]; };
layout(std430, binding = TESSERA_BINDING_COLORS) readonly buffer Colors { uint colors[]; };
layout(std430, binding = TESSERA_BINDING_PICK) readonly buffer Pick { uint pick[]; };
// Per pixel the footprint of its largest splat (point_raster.comp): radius in 1/256 pixels in
// the top 16 bits, the point's position in the pixel in 1/256 (x, bits 8-15) and 1/128 pixels
// (y, bits 1-7), bit 0 set when several points fell on the pixel.
layout(std430, binding = TESSERA_BINDING_SPLAT_RADII) readonly buffer Radii { uint radii[]; };
layout(std430, binding = TESSERA_BINDING_FILL_PYRAMID) buffer Pyramid { uvec2 pyramid[]; };
layout(std430, binding = TESSERA_BINDING_FILL_DEPTH) writeonly buffer OutDepth { uint out_depth[]; };
layout(std430, binding = TESSERA_BINDING_FILL_COLORS) writeonly buffer OutColors { uint out_colors[]; };
layout(std430, binding = TESSERA_BINDING_FILL_PICK) writeonly buffer OutPick { uint out_pick[]; };

uniform int uStage;        // 0: pull level uLevel; 2: push level uLevel; 1: push the pixels
uniform int uLevel;        // stages 0 and 2: the level written, 1..uLevels
uniform uint uWinners;     // first texel of the push phase's winners in `pyramid`
uniform int uLevels;       // coarsest level, <= TESSERA_FILL_MAX_LEVELS
uniform ivec2 uSize;       // level 0 (the frame target) in pixels
uniform float uMaxRadius;  // radii above are clamped to it (pixels)
uniform float uTolerance;  // depth tolerance in splat radii
uniform float uPixelK;     // world size of a pixel at view depth 1 (2 / (P11 height))
uniform float uP22;        // projection[2][2] and [3][2]: view depth from window depth
uniform float uP32;
uniform int uWriteColor;  // copy colours of the winners
uniform int uWritePick;   // copy pick ids of the winners

const uint kEmpty = 0xFFFFFFFFu;

ivec2 levelSize(int l) {
  return (uSize + ivec2((1 << l) - 1)) >> l;
}

// Level l's first texel in `pyramid` (levels 1.. concatenated).
uint levelOffset(int l) {
  uint o = 0u;
  for (int k = 1; k < l; ++k) {
    ivec2 s = levelSize(k);
    o += uint(s.x) * uint(s.y);
  }
  return o;
}

// The texel at `q` of level l (0: the frame target's depth and the pixel itself).
uvec2 texel(int l, ivec2 q, uint offset) {
  if (l == 0) {
    uint i = uint(q.y) * uint(uSize.x) + uint(q.x);
    return uvec2(depth[i], i);
  }
  return pyramid[offset + uint(q.y) * uint(levelSize(l).x) + uint(q.x)];
}

float viewDepth(uint d) {
  return uP32 / ((uintBitsToFloat(d) * 2.0 - 1.0) + uP22);
}

ivec2 pixelOf(uint src) {
  return ivec2(int(src % uint(uSize.x)), int(src / uint(uSize.x)));
}

// The splat of the sample on level-0 pixel `src`: its point's position in pixels (xy) and its
// radius (z, at most uMaxRadius; 0 where no point was drawn as one pixel). Where several points
// fell on the pixel, a disc around the pixel's centre that holds each of their discs (radius
// grown by half the pixel's diagonal).
vec3 footprint(uint src) {
  uint f = radii[src];
  float r = min(float(f >> 16) / 256.0, uMaxRadius);
  if (r == 0.0) return vec3(0.0);
  if ((f & 1u) != 0u) return vec3(vec2(pixelOf(src)) + 0.5, r + 0.70711);
  vec2 in_pixel = (vec2((f >> 8) & 0xFFu, (f >> 1) & 0x7Fu) + 0.5) / vec2(256.0, 128.0);
  return vec3(vec2(pixelOf(src)) + in_pixel, r);
}

void pull() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = levelSize(uLevel);
  if (t.x >= size.x || t.y >= size.y) return;
  ivec2 child_size = levelSize(uLevel - 1);
  uint child_offset = levelOffset(uLevel - 1);
  uvec2 s[4];
  uint front = kEmpty;
  for (int k = 0; k < 4; ++k) {
    ivec2 c = 2 * t + ivec2(k & 1, k >> 1);
    s[k] = c.x < child_size.x && c.y < child_size.y ? texel(uLevel - 1, c, child_offset)
                                                    : uvec2(kEmpty, kEmpty);
    front = min(front, s[k].x);
  }
  uvec2 best = uvec2(kEmpty, kEmpty);
  if (front != kEmpty) {
    // Of the children on the front surface (within the tolerance of the nearest), the sample
    // nearest the texel's centre, which reaches furthest into the neighbourhood the push
    // phase searches; ties by depth, then pixel index, so the pyramid does not depend on timing.
    float front_w = viewDepth(front);
    vec2 centre = (vec2(t) + 0.5) * float(1 << uLevel);
    float best_dist2 = 1e30;
    for (int k = 0; k < 4; ++k) {
      if (s[k].x == kEmpty) continue;
      vec3 f = footprint(s[k].y);
      float w = viewDepth(s[k].x);
      if (w > front_w + uTolerance * max(f.z, 1.0) * w * uPixelK) continue;
      vec2 off = f.xy - centre;
      float dist2 = dot(off, off);
      if (dist2 < best_dist2 ||
          (dist2 == best_dist2 && (s[k].x < best.x || (s[k].x == best.x && s[k].y < best.y)))) {
        best = s[k];
        best_dist2 = dist2;
      }
    }
  }
  pyramid[levelOffset(uLevel) + uint(t.y) * uint(size.x) + uint(t.x)] = best;
}

// The sample kept so far for one pixel or texel.
struct Winner {
  uint src;     // level-0 pixel index, kEmpty: none
  uint d;       // window depth bits
  float w;      // view depth
  float tol;    // depth tolerance of its surface, view depth units
  float dist2;  // squared distance in pixels from its point to the centre filled
};

// Takes sample `s` (depth bits, level-0 pixel) into `best` if its disc reaches within `slack`
// pixels of `at` (pixels) and it lies on the front surface: nearer than the kept one by more
// than the tolerance, or on the same surface and nearer to `at` (then nearer in depth, then the
// smaller index, so the result does not depend on the order of the calls' inputs). `own`: a
// pixel index to leave out.
void consider(inout Winner best, vec2 at, float slack, uint own, uvec2 s) {
  if (s.x == kEmpty || s.y == own || s.y == best.src) return;
  // The disc rule of point_raster.comp: the pixel's centre lies within the splat's radius.
  vec3 f = footprint(s.y);
  vec2 off = at - f.xy;
  float dist2 = dot(off, off);
  float reach = f.z + slack;
  if (f.z == 0.0 || dist2 > reach * reach) return;
  float w = viewDepth(s.x);
  if (best.src != kEmpty) {
    if (w > best.w + best.tol) return;  // behind the kept surface
    bool front = w < best.w - best.tol;
    if (!front && (dist2 > best.dist2 ||
                   (dist2 == best.dist2 && (s.x > best.d || (s.x == best.d && s.y > best.src)))))
      return;
  }
  best.src = s.y;
  best.d = s.x;
  best.w = w;
  best.tol = uTolerance * max(f.z, 1.0) * w * uPixelK;
  best.dist2 = dist2;
}

// The best sample for texel t of level l (level 0: a pixel, its own sample left out). A pixel
// looks at the 3x3 samples around it and the winners of the 3x3 level-1 texels around its
// parent; a texel of level l >= 1 at the samples of level l - 1 under it and a ring of one
// around (4x4: a sample near the edge of a neighbouring block, which that block's own pull may
// not keep, still reaches here) and at the 3x3 winners of level l + 1 around its parent, which
// carry what reaches from further away (the push phase's coarse-to-fine order). A texel above
// level 0 takes samples whose disc reaches any part of it.
Winner gather(int l, ivec2 t, uint own) {
  float scale = float(1 << l);
  vec2 at = (vec2(t) + 0.5) * scale;
  float slack = l == 0 ? 0.0 : 0.70711 * scale;
  Winner best = Winner(kEmpty, kEmpty, 0.0, 0.0, 0.0);
  int fine = max(l - 1, 0);
  ivec2 fine_size = levelSize(fine);
  uint fine_offset = levelOffset(fine);
  ivec2 first = l == 0 ? t - 1 : 2 * t - 1;
  int n = l == 0 ? 3 : 4;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      ivec2 c = first + ivec2(i, j);
      if (c.x < 0 || c.y < 0 || c.x >= fine_size.x || c.y >= fine_size.y) continue;
      consider(best, at, slack, own, texel(fine, c, fine_offset));
    }
  if (l < uLevels) {
    ivec2 coarse_size = levelSize(l + 1);
    uint coarse = uWinners + levelOffset(l + 1);
    for (int j = -1; j <= 1; ++j)
      for (int i = -1; i <= 1; ++i) {
        ivec2 c = (t >> 1) + ivec2(i, j);
        if (c.x < 0 || c.y < 0 || c.x >= coarse_size.x || c.y >= coarse_size.y) continue;
        consider(best, at, slack, own,
                 pyramid[coarse + uint(c.y) * uint(coarse_size.x) + uint(c.x)]);
      }
  }
  return best;
}

// Push, coarse levels (uStage 2): the winners of level uLevel.
void pushLevel() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = levelSize(uLevel);
  if (t.x >= size.x || t.y >= size.y) return;
  Winner best = gather(uLevel, t, kEmpty);
  pyramid[uWinners + levelOffset(uLevel) + uint(t.y) * uint(size.x) + uint(t.x)] =
      uvec2(best.d, best.src);
}

// Push, the pixels (uStage 1): the pixel keeps its own sample unless it has none or the winner
// lies in front of it by more than the tolerance.
void push() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint pixel = uint(p.y) * uint(uSize.x) + uint(p.x);
  Winner best = gather(0, p, pixel);
  uint own = depth[pixel];
  uint src = pixel;
  if (best.src != kEmpty && (own == kEmpty || viewDepth(own) > best.w + best.tol)) src = best.src;
  uint d = src == pixel ? own : best.d;
  out_depth[pixel] = d;
  if (uWriteColor != 0) out_colors[pixel] = d == kEmpty ? kEmpty : colors[src];
  if (uWritePick != 0) out_pick[pixel] = d == kEmpty ? kEmpty : pick[src];
}

void main() {
  if (uStage == 0)
    pull();
  else if (uStage == 2)
    pushLevel();
  else
    push();
}
