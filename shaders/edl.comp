// The eye-dome lighting pass (Boucheny 2009, as in Potree), a screen pass on the resolved image:
// shade = exp(-k * mean over 8 neighbours of max(0, log2 d - log2 d_neighbour)), d the linear
// view depth; neighbours without a point do not count; the image's colour is multiplied by it.
// Needs no normals, reads only depth, so it serves points and meshes alike.
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = TESSERA_BINDING_DEPTH) readonly buffer Depth { uint depth[]; };
layout(std430, binding = TESSERA_BINDING_IMAGE) buffer Image { uint image[]; };

uniform ivec2 uSize;
uniform float uEdlStrength;
uniform int uEdlRadius;  // pixels
uniform float uP22;      // projection[2][2] and [3][2]: linear depth from NDC depth
uniform float uP32;

float logDepth(ivec2 q) {
  uint d = depth[uint(q.y) * uint(uSize.x) + uint(q.x)];
  if (d == 0xFFFFFFFFu) return 0.0;
  float ndc = uintBitsToFloat(d) * 2.0 - 1.0;
  return log2(max(uP32 / (ndc + uP22), 1e-30));
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  if (depth[uint(p.y) * uint(uSize.x) + uint(p.x)] == 0xFFFFFFFFu) return;
  float here = logDepth(p);
  float sum = 0.0;
  const ivec2 dirs[8] = ivec2[8](ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1),
                                 ivec2(1, 1), ivec2(-1, -1), ivec2(1, -1), ivec2(-1, 1));
  for (int k = 0; k < 8; ++k) {
    ivec2 q = clamp(p + dirs[k] * uEdlRadius, ivec2(0), uSize - 1);
    float there = logDepth(q);
    if (there != 0.0) sum += max(0.0, here - there);
  }
  float shade = exp(-sum / 8.0 * 300.0 * uEdlStrength);
  uint out_index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
  uint rgba = image[out_index];
  vec3 c = vec3(rgba & 0xFFu, (rgba >> 8) & 0xFFu, (rgba >> 16) & 0xFFu) * shade;
  uvec3 u = uvec3(clamp(c + 0.5, 0.0, 255.0));
  image[out_index] = u.r | (u.g << 8) | (u.b << 16) | (rgba & 0xFF000000u);
}
