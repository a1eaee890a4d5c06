// Resolves oit_accumulate.comp's sums: C = sum(w a c) / sum(w a) (1 - T) + T B, T = exp(sum
// ln(1 - a)); rows flipped so row 0 is the top.
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = TESSERA_BINDING_IMAGE) writeonly buffer Image { uint image[]; };
layout(std430, binding = TESSERA_BINDING_ACCUM) readonly buffer Sums { float sums[]; };

uniform ivec2 uSize;
uniform vec3 uBackground;  // 0..255

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint k = (uint(p.y) * uint(uSize.x) + uint(p.x)) * 5u;
  float t = exp(sums[k + 4u]);
  vec3 mean = sums[k + 3u] > 0.0 ? vec3(sums[k], sums[k + 1u], sums[k + 2u]) / sums[k + 3u]
                                 : vec3(0.0);
  uvec3 c = uvec3(clamp(mean * (1.0 - t) + uBackground * t + 0.5, 0.0, 255.0));
  uint out_index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
  image[out_index] = c.r | (c.g << 8) | (c.b << 16) | 0xFF000000u;
}
