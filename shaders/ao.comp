// Screen-space ambient occlusion, GTAO-style (render/ao_pass.h has the method, its paper and its
// guarantees; AoPass compiles one program per stage and resolution, see TESSERA_AO_STAGE).
//
// Stage 0, per pixel computed (every pixel, or at half resolution the pixels whose position in
// the whole picture is even both ways): the view point, the normal from the depth, per slice two
// horizons marched through the depth and the slice's visibility in closed form; the ratio of the
// slices' sums is blended into the running mean (weight uBlend; 1 replaces it).
// Stage 1: the mean blurred over 5x5 computed pixels where the depth is one surface.
// Stage 2, per pixel: the (denoised) mean, at half resolution from the four nearest computed
// pixels on the same surface, into the visibility plane; the image multiplied by it^strength.
layout(local_size_x = 16, local_size_y = 16) in;

// The frame's depth and the computed plane stages 1 and 2 read, as buffer textures (llvmpipe
// gathers texels with vector code, where it reads a storage buffer lane by lane).
layout(binding = TESSERA_TEXTURE_DEPTH) uniform usamplerBuffer uDepth;
layout(binding = TESSERA_AO_TEXTURE_PLANE) uniform samplerBuffer uPlane;
layout(std430, binding = TESSERA_BINDING_IMAGE) buffer Image { uint image[]; };
// Per computed pixel (raster order over uGrid): the running mean of the visibility, kNone where
// the pixel is empty.
layout(std430, binding = TESSERA_AO_BINDING_MEAN) buffer Mean { float mean_plane[]; };
// Per computed pixel: the denoised mean (stage 1).
layout(std430, binding = TESSERA_AO_BINDING_DENOISED) writeonly buffer Denoised {
  float denoised[];
};
// Per pixel of the target (raster order): what multiplied the image, kNone where empty.
layout(std430, binding = TESSERA_AO_BINDING_VISIBILITY) writeonly buffer Visibility {
  float visibility[];
};

uniform ivec2 uSize;    // the target, pixels
uniform ivec2 uGrid;    // the computed plane (half resolution: about half each way)
uniform ivec2 uParity;  // half resolution: computed pixel (i, j) is target pixel 2 (i, j) + uParity
uniform ivec2 uOrigin;  // the target's pixel (0, 0) in the whole picture
uniform vec2 uNdcScale;      // 2 / uSize: NDC x = (x + 0.5) uNdcScale.x - 1
uniform vec4 uProjection;    // projection [0][0], [1][1], [2][0], [2][1] (off-axis frusta)
uniform float uP22;          // projection[2][2] and [3][2]: linear depth from NDC depth
uniform float uP32;
uniform float uPixelScale;   // pixels a unit spans at view depth 1 (projection[1][1] height / 2)
uniform float uRadius;       // view units; <= 0: uRadiusPx at every depth
uniform float uRadiusPx;
uniform int uSlices;
uniform int uSteps;
uniform uint uFrameDirection;  // this frame's rotation of the slices, table entries
uniform uint uFrameJitter;     // this frame's shift of the step offsets, 1/65536 of a step
uniform float uBlend;          // the frame's weight in the running mean (1: replaces it)
uniform float uEdgeTau;  // same surface: linear depths within uEdgeTau z (1 + pixels apart)
uniform float uStrength;
// The slice directions over half a turn (kAoDirections = 256), two to an element: computed in
// double on the CPU so the reference in the tests reads the same floats.
uniform vec4 uDirections[128];

const float kNone = -1.0;
const float kHalfPi = 1.5707963267948966;
const uint kEmpty = 0xFFFFFFFFu;

uint depthBits(ivec2 q) {
  return texelFetch(uDepth, q.y * uSize.x + q.x).x;
}

bool inside(ivec2 q) {
  return q.x >= 0 && q.y >= 0 && q.x < uSize.x && q.y < uSize.y;
}

float linearDepth(uint bits) {
  precise float ndc = uintBitsToFloat(bits) * 2.0 - 1.0;
  precise float z = uP32 / (ndc + uP22);
  return z;
}

// The view-space point of pixel q at depth plane value `bits` (not empty), through the
// projection's own terms, so off-axis frusta unproject right. `precise`: no fused multiply-adds,
// so the reference in the tests computes the same floats.
vec3 viewPoint(ivec2 q, uint bits) {
  precise float z = linearDepth(bits);
  precise vec2 ndc = (vec2(q) + 0.5) * uNdcScale - 1.0;
  precise vec2 xy = z * (ndc + uProjection.zw) / uProjection.xy;
  return vec3(xy, -z);
}

// The target pixel a computed pixel stands for.
ivec2 targetPixel(ivec2 g) {
#if TESSERA_AO_HALF
  return 2 * g + uParity;
#else
  return g;
#endif
}

#if TESSERA_AO_STAGE == 0
// PCG (O'Neill 2014) as a 32-bit hash: Jarzynski and Olano, "Hash Functions for GPU
// Rendering", JCGT 9(3), 2020.
uint pcg(uint v) {
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

vec2 direction(uint index) {
  vec4 pair = uDirections[index >> 1];
  return (index & 1u) != 0u ? pair.zw : pair.xy;
}

// The surface normal at p (view point P) from the depth: per axis the one-sided difference to
// the side whose two neighbours continue p's depth in a straight line (window depth is affine
// in screen position on a plane), so a pixel beside a crease or a silhouette takes its own
// face's slope (J. Turanszki, "Improved normal reconstruction from depth", 2021); facing the eye.
vec3 normalAt(ivec2 p, vec3 P, uint bits) {
  vec3 d[2];
  precise float dp = uintBitsToFloat(bits);
  for (int axis = 0; axis < 2; ++axis) {
    ivec2 step = axis == 0 ? ivec2(1, 0) : ivec2(0, 1);
    ivec2 a = p + step, b = p - step;
    uint da = inside(a) ? depthBits(a) : kEmpty;
    uint db = inside(b) ? depthBits(b) : kEmpty;
    uint daa = inside(a + step) ? depthBits(a + step) : kEmpty;
    uint dbb = inside(b - step) ? depthBits(b - step) : kEmpty;
    // The error of p's depth extrapolated from each side (a side without its second neighbour
    // only when the other has no neighbour at all).
    precise float ea = da != kEmpty && daa != kEmpty
                           ? abs(dp - 2.0 * uintBitsToFloat(da) + uintBitsToFloat(daa))
                           : 1e30;
    precise float eb = db != kEmpty && dbb != kEmpty
                           ? abs(dp - 2.0 * uintBitsToFloat(db) + uintBitsToFloat(dbb))
                           : 1e30;
    bool use_a = da != kEmpty && (db == kEmpty || ea <= eb);
    vec3 A = da != kEmpty ? viewPoint(a, da) : P;
    vec3 B = db != kEmpty ? viewPoint(b, db) : P;
    d[axis] = use_a ? A - P : P - B;
  }
  vec3 n = cross(d[0], d[1]);
  float len = length(n);
  if (!(len > 0.0)) return normalize(-P);  // a lone pixel: facing the eye
  n /= len;
  return dot(n, P) > 0.0 ? -n : n;
}

float gtao(ivec2 p, uint bits) {
  vec3 P = viewPoint(p, bits);
  vec3 V = normalize(-P);
  vec3 N = normalAt(p, P, bits);
  precise float z = -P.z;
  precise float r_px = uRadius > 0.0 ? uRadius * uPixelScale / z : uRadiusPx;
  r_px = clamp(r_px, 1.0, TESSERA_AO_MAX_RADIUS_PX);
  float r = r_px * z / uPixelScale;  // view units, after the clamp
  // The falloff: full weight to (1 - kAoFalloff) r, none at r.
  float falloff_mul = -1.0 / (TESSERA_AO_FALLOFF * r), falloff_add = 1.0 / TESSERA_AO_FALLOFF;
  uvec2 global = uvec2(p + uOrigin);
  uint h = pcg(global.x + pcg(global.y));
  uint h2 = pcg(h);
  uint base = (h & 255u) + uFrameDirection;
  float jitter = float((h2 + uFrameJitter) & 0xFFFFu) / 65536.0;
  float sum = 0.0, open = 0.0;
  for (int slice = 0; slice < uSlices; ++slice) {
    vec2 dir = direction((base + uint(slice * 256 / uSlices)) & 255u);
    vec3 dir_view = vec3(dir, 0.0);
    vec3 ortho = dir_view - dot(dir_view, V) * V;
    vec3 axis = normalize(cross(ortho, V));
    vec3 np = N - axis * dot(N, axis);
    float np_len = length(np);
    if (!(np_len > 1e-6)) continue;
    float cos_n = clamp(dot(np, V) / np_len, -1.0, 1.0);
    float n = (dot(ortho, np) < 0.0 ? -1.0 : 1.0) * acos(cos_n);
    float sin_n = sin(n);
    // Per side the sine of the highest elevation above the slice's tangent line (0: the tangent
    // line; below it nothing occludes). A tap's elevation is measured against the normal rather
    // than as its angle from V: both are the same for a tap in the slice's plane, but a tap
    // rounded to a pixel centre lies a little off that plane, and there only the normal's
    // measure keeps a plane's own taps at elevation 0 (the angle from V scatters them above and
    // below the tangent: up to 0.05 of occlusion per pixel on a plane tilted 60 degrees).
    float e0 = 0.0, e1 = 0.0;
    float to_sine = 1.0 / np_len;
    for (int k = 0; k < uSteps; ++k) {
      precise float s = (float(k) + jitter) / float(uSteps);
      precise float t = 1.0 + s * s * (r_px - 1.0);
      precise vec2 offset = dir * t;
      ivec2 o = ivec2(floor(offset + 0.5));
      for (int side = 0; side < 2; ++side) {
        ivec2 q = side == 0 ? p + o : p - o;
        if (!inside(q)) continue;
        uint dq = depthBits(q);
        if (dq == kEmpty) continue;
        vec3 delta = viewPoint(q, dq) - P;
        float dist = length(delta);
        if (!(dist > 0.0)) continue;
        // The falloff pulls a far tap's elevation down to the tangent line.
        float w = clamp(dist * falloff_mul + falloff_add, 0.0, 1.0);
        float e = w * dot(delta, N) / dist * to_sine;
        if (side == 0)
          e0 = max(e0, e);
        else
          e1 = max(e1, e);
      }
    }
    // The horizon angles from V, within the hemisphere around the projected normal.
    float h0 = n - kHalfPi + asin(min(e1, 1.0));
    float h1 = n + kHalfPi - asin(min(e0, 1.0));
    // The paper's inner integral of cos(theta - n) |sin theta| from h0 to h1, and its value
    // unoccluded (h = n -/+ pi/2): cos n + n sin n.
    sum += np_len * 0.25 *
           (-cos(2.0 * h0 - n) + cos_n + 2.0 * h0 * sin_n - cos(2.0 * h1 - n) + cos_n +
            2.0 * h1 * sin_n);
    open += np_len * (cos_n + n * sin_n);
  }
  return open > 0.0 ? clamp(sum / open, 0.0, 1.0) : 1.0;
}
#endif

#if TESSERA_AO_STAGE == 1
// The 5x5 binomial weights (1 4 6 4 1 each way).
const float kBinomial[5] = float[5](1.0, 4.0, 6.0, 4.0, 1.0);

float denoise(ivec2 g, float centre) {
  float z = linearDepth(depthBits(targetPixel(g)));
  float sum = 0.0, weight = 0.0;
  for (int dy = -TESSERA_AO_DENOISE_RADIUS; dy <= TESSERA_AO_DENOISE_RADIUS; ++dy)
    for (int dx = -TESSERA_AO_DENOISE_RADIUS; dx <= TESSERA_AO_DENOISE_RADIUS; ++dx) {
      ivec2 q = g + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= uGrid.x || q.y >= uGrid.y) continue;
      float v = texelFetch(uPlane, q.y * uGrid.x + q.x).x;
      if (v < 0.0) continue;
      ivec2 pq = targetPixel(q);
      if (!inside(pq)) continue;
      float zq = linearDepth(depthBits(pq));
      float apart = length(vec2(pq - targetPixel(g)));
      if (abs(zq - z) > uEdgeTau * z * (1.0 + apart)) continue;
      float w = kBinomial[dx + 2] * kBinomial[dy + 2];
      sum += w * v;
      weight += w;
    }
  return weight > 0.0 ? sum / weight : centre;
}
#endif

#if TESSERA_AO_STAGE == 2
void shadeImage(ivec2 p, float shade) {
  uint index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
  uint rgba = image[index];
  vec3 c = vec3(rgba & 0xFFu, (rgba >> 8) & 0xFFu, (rgba >> 16) & 0xFFu) * shade;
  uvec3 u = uvec3(clamp(c + 0.5, 0.0, 255.0));
  image[index] = u.r | (u.g << 8) | (u.b << 16) | (rgba & 0xFF000000u);
}

float planeAt(ivec2 g) {
  return texelFetch(uPlane, g.y * uGrid.x + g.x).x;
}

#if TESSERA_AO_HALF
// The joint bilateral upsample: the four computed pixels around p, bilinear weights, only those
// on p's surface; none there: the computed pixel of the 3x3 around with the nearest depth.
float upsample(ivec2 p, uint bits) {
  float z = linearDepth(bits);
  ivec2 rel = p - uParity;
  ivec2 g0 = ivec2(floor(vec2(rel) * 0.5));
  vec2 f = vec2(rel) * 0.5 - vec2(g0);
  float sum = 0.0, weight = 0.0, nearest = kNone, nearest_dz = 1e30;
  for (int k = 0; k < 9; ++k) {
    ivec2 g = g0 + ivec2(k % 3 - 1, k / 3 - 1);
    if (g.x < 0 || g.y < 0 || g.x >= uGrid.x || g.y >= uGrid.y) continue;
    float v = planeAt(g);
    if (v < 0.0) continue;
    ivec2 q = targetPixel(g);
    float dz = abs(linearDepth(depthBits(q)) - z);
    if (dz < nearest_dz) {
      nearest_dz = dz;
      nearest = v;
    }
    ivec2 cell = g - g0;
    if (cell.x < 0 || cell.y < 0) continue;  // the bilinear cells are g0 .. g0 + 1
    if (dz > uEdgeTau * z * (1.0 + length(vec2(q - p)))) continue;
    float w = (cell.x == 0 ? 1.0 - f.x : f.x) * (cell.y == 0 ? 1.0 - f.y : f.y);
    sum += w * v;
    weight += w;
  }
  if (weight > 0.0) return sum / weight;
  return nearest >= 0.0 ? nearest : 1.0;
}
#endif
#endif

void main() {
#if TESSERA_AO_STAGE == 0
  ivec2 g = ivec2(gl_GlobalInvocationID.xy);
  if (g.x >= uGrid.x || g.y >= uGrid.y) return;
  uint index = uint(g.y) * uint(uGrid.x) + uint(g.x);
  ivec2 p = targetPixel(g);
  uint bits = inside(p) ? depthBits(p) : kEmpty;
  if (bits == kEmpty) {
    mean_plane[index] = kNone;
    return;
  }
  float v = gtao(p, bits);
  float before = mean_plane[index];
  mean_plane[index] = uBlend >= 1.0 || before < 0.0 ? v : mix(before, v, uBlend);
#elif TESSERA_AO_STAGE == 1
  ivec2 g = ivec2(gl_GlobalInvocationID.xy);
  if (g.x >= uGrid.x || g.y >= uGrid.y) return;
  uint index = uint(g.y) * uint(uGrid.x) + uint(g.x);
  float centre = texelFetch(uPlane, int(index)).x;
  denoised[index] = centre < 0.0 ? kNone : denoise(g, centre);
#else
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (!inside(p)) return;
  uint index = uint(p.y) * uint(uSize.x) + uint(p.x);
  uint bits = depthBits(p);
  if (bits == kEmpty) {
    visibility[index] = kNone;
    return;
  }
#if TESSERA_AO_HALF
  float v = upsample(p, bits);
#else
  float v = planeAt(p);
  if (v < 0.0) v = 1.0;
#endif
  visibility[index] = v;
  if (v < 1.0 && uStrength > 0.0) shadeImage(p, pow(v, uStrength));  // 0: visibility only
#endif
}
