// Compute-shader point rasterisation (DESIGN.md: GL_POINTS draws ~5 M points/s on llvmpipe, a
// compute atomicMin scatter ~100 M points/s). Without 64-bit atomics the nearest point wins in
// two passes over the same points: pass 0 keeps the smallest depth per pixel (atomicMin on the
// depth's float bits, which order like the floats for depths in [0, 1]); pass 1, among points at
// that depth, keeps the smallest point index, so the result is the same whatever the thread
// order. Splats are round, `uRadius` pixels, sized from the node spacing by the caller.
layout(local_size_x = 128) in;

struct Point {
  vec3 position;  // relative to the batch's node
  uint rgba;      // r in the low byte
};
layout(std430, binding = 0) readonly buffer Points { Point points[]; };
layout(std430, binding = 1) buffer Depth { uint depth[]; };
layout(std430, binding = 2) buffer Ids { uint ids[]; };

uniform mat4 uClip;     // clip from the batch's node frame
uniform uint uFirst;    // first point of the batch in `points`
uniform uint uCount;
uniform ivec2 uSize;    // viewport in pixels
uniform int uRadius;
uniform int uPass;      // 0: depth, 1: id

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= uCount) return;
  uint gi = uFirst + i;
  vec4 c = uClip * vec4(points[gi].position, 1.0);
  if (c.w <= 0.0) return;
  vec3 ndc = c.xyz / c.w;
  if (ndc.z < -1.0 || ndc.z > 1.0) return;
  ivec2 centre = ivec2(floor((ndc.xy * 0.5 + 0.5) * vec2(uSize)));
  uint d = floatBitsToUint(ndc.z * 0.5 + 0.5);
  int r2 = uRadius * uRadius + uRadius;
  for (int dy = -uRadius; dy <= uRadius; ++dy) {
    for (int dx = -uRadius; dx <= uRadius; ++dx) {
      if (dx * dx + dy * dy > r2) continue;
      ivec2 q = centre + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y) continue;
      uint idx = uint(q.y) * uint(uSize.x) + uint(q.x);
      if (uPass == 0) {
        atomicMin(depth[idx], d);
      } else if (depth[idx] == d) {
        atomicMin(ids[idx], gi);
      }
    }
  }
}
