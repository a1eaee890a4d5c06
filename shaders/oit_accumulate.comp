// Order-independent blending of see-through points, the baselines SPBR is measured against
// (bench/spbr): every point once, a disc of its node's spacing, opacity alpha_p per point such
// that the m discs a surface stacks on a pixel give the model's alpha (1 - (1 - alpha_p)^m =
// alpha). uMode 0, "weighted average": C = sum(alpha_p c) / sum(alpha_p) (1 - T) + T B;
// uMode 1, weighted blended OIT (McGuire and Bavoil 2013, their depth weight
// w = alpha max(1e-2, 3e3 (1 - z)^3)): C = sum(w alpha_p c) / sum(w alpha_p) (1 - T) + T B;
// both with T = prod(1 - alpha_p) = exp(sum ln(1 - alpha_p)). Sums are float atomics
// (GL_NV_shader_atomic_float), so the result depends slightly on thread order.
#extension GL_NV_shader_atomic_float : require
layout(local_size_x = 128) in;

// struct Point: shaders/shared_layout.h
layout(std430, binding = TESSERA_BINDING_POINTS) readonly buffer Points { Point points[]; };
layout(std430, binding = TESSERA_BINDING_ACCUM) buffer Sums { float sums[]; };  // 5 floats a pixel

uniform mat4 uClip;
uniform uint uColorOverride;  // non-zero: 0x1000000 | rgb for every point of the batch
uniform uint uCount;
uniform ivec2 uSize;
uniform float uDiscK;   // disc radius in pixels at view depth 1
uniform float uAlpha;   // alpha_p
uniform int uMode;
uniform int uMaxRadius;

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= uCount) return;
  if (tesseraClipped(points[i].position)) return;  // cut away by a CLIP node
  vec4 c = uClip * vec4(points[i].position, 1.0);
  if (c.w <= 0.0) return;
  vec3 ndc = c.xyz / c.w;
  if (ndc.z < -1.0 || ndc.z > 1.0) return;
  vec2 pos = (ndc.xy * 0.5 + 0.5) * vec2(uSize);
  ivec2 centre = ivec2(floor(pos));
  float r = uDiscK / c.w;
  float z = ndc.z * 0.5 + 0.5;
  float w = uMode == 1 ? max(1e-2, 3e3 * pow(1.0 - z, 3.0)) : 1.0;
  uint rgba = uColorOverride != 0u ? uColorOverride : points[i].rgba;
  vec3 color = vec3(rgba & 0xFFu, (rgba >> 8) & 0xFFu, (rgba >> 16) & 0xFFu);
  float wa = w * uAlpha;
  float log_t = log(max(1.0 - uAlpha, 1e-6));
  int reach = min(int(floor(r + 0.5)), uMaxRadius);
  for (int dy = -reach; dy <= reach; ++dy) {
    for (int dx = -reach; dx <= reach; ++dx) {
      ivec2 q = centre + ivec2(dx, dy);
      vec2 off = vec2(q) + 0.5 - pos;
      if ((dx != 0 || dy != 0) && dot(off, off) > r * r) continue;
      if (q.x < 0 || q.y < 0 || q.x >= uSize.x || q.y >= uSize.y) continue;
      uint k = (uint(q.y) * uint(uSize.x) + uint(q.x)) * 5u;
      atomicAdd(sums[k], wa * color.r);
      atomicAdd(sums[k + 1u], wa * color.g);
      atomicAdd(sums[k + 2u], wa * color.b);
      atomicAdd(sums[k + 3u], wa);
      atomicAdd(sums[k + 4u], log_t);
    }
  }
}
