// Opaque overlay lines (avatars' frusta, sketches; OverlayPass in render/src/overlay_pass.cpp)
// written straight into the frame target's image, instead of rasterised as long thin quads:
// llvmpipe bins and steps a thin triangle over every 64x64 tile and 4x4 block its box touches,
// which cost a wall node most of the overlay pass for 16 sites' frusta (2 ms for 11,000 line
// pixels at 640x360), while these walk only the pixels along each line.
//
// A line covers the pixels whose centres lie in its rectangle: from `half` before its first end
// to `half` past its second, `half` either side (the quad the raster path would draw). Two
// passes, an invocation per step along a line's major axis (a column or row of it on screen;
// the CPU lists which line each step belongs to, so short and long lines fill the SIMD lanes
// alike):
//   PASS 0: each covered pixel that passes the depth test (not behind the scene's nearest
//           surface) takes atomicMax(owner, line + 1): the latest line wins, as later quads
//           drew over earlier ones.
//   PASS 1: the owner writes its colour into the image and clears the owner word, so the plane
//           is all zero again for the next frame (a line that does not own a pixel sees another
//           line's id or 0 and leaves it).
layout(local_size_x = 64) in;

layout(std430, binding = TESSERA_BINDING_OVERLAY_LINES) readonly buffer Lines { OverlayLine lines[]; };
layout(std430, binding = TESSERA_BINDING_OVERLAY_STEPS) readonly buffer Steps { uint step_line[]; };
layout(std430, binding = TESSERA_BINDING_OVERLAY_OWNER) buffer Owner { uint owner[]; };  // top row first
layout(std430, binding = TESSERA_BINDING_DEPTH) readonly buffer Depth { uint depth[]; };  // bottom row first
layout(std430, binding = TESSERA_BINDING_IMAGE) buffer Image { uint image[]; };  // top row first

uniform ivec2 uSize;
uniform uint uFirst;  // the first step of this dispatch (a dispatch holds at most 65535 groups)
uniform uint uSteps;  // steps in all

// Whether a pixel centre at `distance` inside an edge whose outward normal is `normal` is
// covered: inside, or exactly on a left or top edge, as the rasteriser's tie rule has it, so
// an axis-aligned line on pixel edges covers the columns and rows its quad would.
bool inside(float distance, vec2 normal) {
  return distance > 0.0 || (distance == 0.0 && (normal.x < 0.0 || (normal.x == 0.0 && normal.y < 0.0)));
}

void main() {
  uint step = uFirst + gl_GlobalInvocationID.x;
  if (step >= uSteps) return;
  uint id = step_line[step];
  OverlayLine l = lines[id];
  // This invocation's column (x-major lines) or row: the line's first one on screen plus the
  // step's place among the line's steps.
  bool x_major = (l.flags & 1u) != 0u;
  int m = l.first + int(step - l.base);
  vec2 a = l.ends.xy, b = l.ends.zw;
  float half_w = l.depth.z;
  vec2 d = b - a;
  float len = length(d);
  vec2 dir = len > 1e-6 ? d / len : vec2(1.0, 0.0);
  vec2 across = vec2(-dir.y, dir.x);
  // Across: the pixels the rectangle's cross-section (with its caps) can reach at this step.
  float slope = x_major ? (abs(d.x) > 1e-6 ? d.y / d.x : 0.0) : (abs(d.y) > 1e-6 ? d.x / d.y : 0.0);
  float reach = half_w * sqrt(1.0 + slope * slope) + half_w * abs(slope) + 1.0;
  float centre_major = float(m) + 0.5;
  float t_axis = x_major ? (abs(d.x) > 1e-6 ? (centre_major - a.x) / d.x : 0.0)
                         : (abs(d.y) > 1e-6 ? (centre_major - a.y) / d.y : 0.0);
  float minor_at = x_major ? a.y + t_axis * d.y : a.x + t_axis * d.x;
  int n0 = max(int(floor(minor_at - reach)), 0);
  int n1 = min(int(ceil(minor_at + reach)), (x_major ? uSize.y : uSize.x) - 1);
  for (int n = n0; n <= n1; ++n) {
    ivec2 p = x_major ? ivec2(m, n) : ivec2(n, m);
    vec2 c = vec2(p) + 0.5;
    float along = dot(c - a, dir), side = dot(c - a, across);
    if (!inside(along + half_w, -dir) || !inside(len + half_w - along, dir) ||
        !inside(half_w - side, across) || !inside(half_w + side, -across))
      continue;
    uint idx = uint(p.y) * uint(uSize.x) + uint(p.x);
#if PASS == 0
    if (l.depth.w != 0.0) {
      float z = l.depth.x + l.depth.y * along;
      uint s = depth[uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x)];
      if (s != 0xFFFFFFFFu && z > uintBitsToFloat(s)) continue;
    }
    atomicMax(owner[idx], id + 1u);
#else
    if (owner[idx] == id + 1u) {
      image[idx] = (image[idx] & 0xFF000000u) | (l.rgb & 0xFFFFFFu);
      owner[idx] = 0u;
    }
#endif
  }
}
