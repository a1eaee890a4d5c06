// The multi-view AO grid (render/ao_grid.h; Sabbadin et al. 2016, section 6): stage 0 scatters a
// frame's screen-space visibility into the sparse grid, stage 1 shades the image from it.
// Cells are keyed x | y << 9 | z << 18, plus 1 (0 marks an empty slot), in a hash table with
// linear probing; sums are 20.12 fixed point, added atomically, so the order of the adds does
// not change them.
layout(local_size_x = 16, local_size_y = 16) in;

layout(binding = TESSERA_TEXTURE_DEPTH) uniform usamplerBuffer uDepth;
layout(std430, binding = TESSERA_BINDING_IMAGE) buffer Image { uint image[]; };
layout(std430, binding = TESSERA_AO_GRID_BINDING_KEYS) buffer Keys { uint keys[]; };
layout(std430, binding = TESSERA_AO_GRID_BINDING_SUMS) buffer Sums { uvec2 sums[]; };
layout(std430, binding = TESSERA_AO_GRID_BINDING_VISIBILITY) readonly buffer Visibility {
  float visibility[];
};

uniform ivec2 uSize;
uniform int uStride;          // stage 0: every uStride-th pixel each way
uniform mat4 uCameraFromClip;  // unprojects a pixel centre at its window depth
uniform mat4 uGridFromCamera;  // camera space to grid coordinates (cells; the corner at 0)
uniform float uFar;            // w_d's d_max: the grid's extent, camera units
uniform float uStrength;

const uint kEmpty = 0xFFFFFFFFu;
const uint kSlots = TESSERA_AO_GRID_SLOTS;
const int kSide = TESSERA_AO_GRID_SIDE;
const int kProbes = 32;
const float kFixed = 4096.0;  // 20.12 fixed point: a million full-weight samples a cell

uint pcg(uint v) {
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

// Camera-space point of pixel q at window depth bits.
vec3 cameraPoint(ivec2 q, uint bits) {
  vec2 ndc = (vec2(q) + 0.5) / vec2(uSize) * 2.0 - 1.0;
  vec4 v = uCameraFromClip * vec4(ndc, uintBitsToFloat(bits) * 2.0 - 1.0, 1.0);
  return v.xyz / v.w;
}

uint depthAt(ivec2 q) {
  if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y) return kEmpty;
  return texelFetch(uDepth, q.y * uSize.x + q.x).x;
}

// The key of the cell holding grid coordinates g, 0 outside the grid.
uint keyOf(ivec3 c) {
  if (any(lessThan(c, ivec3(0))) || any(greaterThanEqual(c, ivec3(kSide)))) return 0u;
  return (uint(c.x) | (uint(c.y) << 9) | (uint(c.z) << 18)) + 1u;
}

// The slot holding `key`, or kEmpty (stage 1: not there; stage 0: the table is full there).
uint find(uint key, bool insert) {
  uint slot = pcg(key) & (kSlots - 1u);
  for (int i = 0; i < kProbes; ++i) {
    uint k = insert ? atomicCompSwap(keys[slot], 0u, key) : keys[slot];
    if (k == key || (insert && k == 0u)) return slot;
    if (k == 0u) return kEmpty;
    slot = (slot + 1u) & (kSlots - 1u);
  }
  return kEmpty;
}

void main() {
  ivec2 id = ivec2(gl_GlobalInvocationID.xy);
#if TESSERA_AO_GRID_STAGE == 0
  ivec2 p = id * uStride;
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint bits = depthAt(p);
  float v = visibility[p.y * uSize.x + p.x];
  if (bits == kEmpty || !(v >= 0.0)) return;
  vec3 P = cameraPoint(p, bits);
  // The normal from the neighbours uStride pixels right (or left) and up (or down).
  ivec2 dx = ivec2(uStride, 0), dy = ivec2(0, uStride);
  uint bx = depthAt(p + dx), by = depthAt(p + dy);
  if (bx == kEmpty) {
    dx = -dx;
    bx = depthAt(p + dx);
  }
  if (by == kEmpty) {
    dy = -dy;
    by = depthAt(p + dy);
  }
  if (bx == kEmpty || by == kEmpty) return;
  vec3 n = cross(cameraPoint(p + dx, bx) - P, cameraPoint(p + dy, by) - P);
  float len = length(n);
  if (!(len > 0.0)) return;
  n /= len;
  vec3 l = normalize(-P);  // towards the eye
  // Equation 11: views facing the surface count more; equation 10: nearer views count more.
  float wn = abs(dot(n, l));
  float wd = max(1.0 - length(P) / uFar, 0.1);
  float w = wn * wd;
  if (!(w > 0.0)) return;
  uint key = keyOf(ivec3(floor((uGridFromCamera * vec4(P, 1.0)).xyz)));
  if (key == 0u) return;
  uint slot = find(key, true);
  if (slot == kEmpty) return;
  atomicAdd(sums[slot].x, uint(w * clamp(v, 0.0, 1.0) * kFixed + 0.5));
  atomicAdd(sums[slot].y, uint(w * kFixed + 0.5));
#else
  ivec2 p = id;
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint bits = depthAt(p);
  if (bits == kEmpty) return;
  vec3 g = (uGridFromCamera * vec4(cameraPoint(p, bits), 1.0)).xyz - 0.5;
  ivec3 base = ivec3(floor(g));
  vec3 f = g - vec3(base);
  float sum = 0.0, weight = 0.0;
  for (int corner = 0; corner < 8; ++corner) {
    ivec3 o = ivec3(corner & 1, (corner >> 1) & 1, corner >> 2);
    uint key = keyOf(base + o);
    if (key == 0u) continue;
    uint slot = find(key, false);
    if (slot == kEmpty) continue;
    uvec2 s = sums[slot];
    if (s.y == 0u) continue;
    vec3 t = mix(1.0 - f, f, vec3(o));
    float tri = t.x * t.y * t.z;
    sum += tri * float(s.x) / float(s.y);
    weight += tri;
  }
  if (!(weight > 0.0)) return;
  float shade = pow(clamp(sum / weight, 0.0, 1.0), uStrength);
  uint index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
  uint rgba = image[index];
  vec3 c = vec3(rgba & 0xFFu, (rgba >> 8) & 0xFFu, (rgba >> 16) & 0xFFu) * shade;
  uvec3 u = uvec3(clamp(c + 0.5, 0.0, 255.0));
  image[index] = u.r | (u.g << 8) | (u.b << 16) | (rgba & 0xFF000000u);
#endif
}
