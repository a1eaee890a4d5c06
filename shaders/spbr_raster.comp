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
layout(local_size_x = 128) in;

struct Point {
  vec3 position;
  uint rgba;
};
layout(std430, binding = 0) readonly buffer Points { Point points[]; };
layout(std430, binding = 1) buffer Depth { uint depth[]; };    // uGroupCount layers
layout(std430, binding = 2) buffer Colors { uint colors[]; };  // uGroupCount layers
layout(std430, binding = 4) readonly buffer Normals { uint normals[]; };  // 10:10:10 snorm
layout(std430, binding = 6) readonly buffer Ratios { float ratios[]; };   // node / local density

uniform mat4 uClip;
uniform uint uColorOverride;  // non-zero: 0x1000000 | rgb for every point of the batch
uniform uint uCount;
uniform ivec2 uSize;
uniform float uDiscK;     // disc radius in pixels at view depth 1
uniform float uK;         // copies per point over all uTotal ensembles, <= uTotal
uniform uint uTotal;      // L
uniform uint uGroupFirst;
uniform uint uGroupCount;
uniform uint uSeed;       // stable key of the node
uniform int uPass;        // 0: depth, 1: colour
uniform int uMaxRadius;
uniform int uSlantOff;    // 1: cross-section s cos(theta), from the point's normal
uniform vec3 uEyeLocal;   // the eye in the batch's frame (for theta)
uniform int uHasRatios;   // 1: scale k by each point's density ratio (density jumps in a node)
uniform int uOneLayer;    // 1: every ensemble into layer 0 (one opaque pass, a speed baseline)

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
  uint base = uOneLayer != 0 ? 0u : layer * uint(uSize.x) * uint(uSize.y);
  for (int dy = -reach; dy <= reach; ++dy) {
    for (int dx = -reach; dx <= reach; ++dx) {
      ivec2 q = centre + ivec2(dx, dy);
      vec2 off = vec2(q) + 0.5 - pos;
      if (dot(off, off) > r * r) continue;
      if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y) continue;
      uint idx = base + uint(q.y) * uint(uSize.x) + uint(q.x);
      if (uPass == 0) {
        atomicMin(depth[idx], d);
      } else if (depth[idx] == d) {
        atomicMin(colors[idx], rgb);
      }
    }
  }
}

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= uCount) return;
  uint h = hash(uSeed ^ hash(i + 0x9e3779b9u));
  float k = uHasRatios != 0 ? uK * ratios[i] : uK;
  float whole = floor(k);
  float u = float(hash(h ^ 0x85ebca6bu) >> 8) * (1.0 / 16777216.0);
  uint copies = min(uint(whole) + (u < k - whole ? 1u : 0u), uTotal);
  if (copies == 0u) return;
  // Copies sit in ensembles e0, e0 + 1, ... (mod L); a is the copy index of uGroupFirst.
  uint e0 = h % uTotal;
  uint a = (uGroupFirst + uTotal - e0) % uTotal;
  bool any = a < copies || a + uGroupCount > uTotal;
  if (!any) return;

  vec4 c = uClip * vec4(points[i].position, 1.0);
  if (c.w <= 0.0) return;
  vec3 ndc = c.xyz / c.w;
  if (ndc.z < -1.0 || ndc.z > 1.0) return;
  vec2 pos = (ndc.xy * 0.5 + 0.5) * vec2(uSize);
  ivec2 centre = ivec2(floor(pos));
  uint d = floatBitsToUint(ndc.z * 0.5 + 0.5);
  float r = uDiscK / c.w;
  if (uSlantOff != 0) {
    // s cos(theta): the disc's area shrinks with the angle between the surface normal and the
    // line of sight, cancelling eq. 2's gain on slanted surfaces.
    uint bits = normals[i];
    vec3 n = vec3(float(int(bits << 22) >> 22), float(int(bits << 12) >> 22),
                  float(int(bits << 2) >> 22)) / 511.0;
    vec3 view = normalize(uEyeLocal - points[i].position);
    float cosine = abs(dot(normalize(n + 1e-9), view));
    r *= sqrt(max(cosine, 0.02));
  }
  uint rgb = uColorOverride != 0u ? uColorOverride & 0xFFFFFFu : points[i].rgba & 0xFFFFFFu;
  // Copies c in [a, a + count) map to layers c - a; wrapping past L, copies [0, ...) follow.
  for (uint cc = a; cc < min(a + uGroupCount, copies); ++cc) splat(cc - a, pos, centre, r, d, rgb);
  if (a + uGroupCount > uTotal) {
    uint wrap = a + uGroupCount - uTotal;
    for (uint cc = 0u; cc < min(wrap, copies); ++cc) splat(cc + uTotal - a, pos, centre, r, d, rgb);
  }
}
