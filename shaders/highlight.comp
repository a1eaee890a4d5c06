// The highlight pass (screen_passes.h, issue 16): tints the pixels whose surface point, seen
// through the lasso's view, falls inside the lasso. The pixel's NDC (its centre and its depth)
// goes through uLassoFromNdc (the lasso's clip-from-world times this view's world-from-clip,
// composed in double on the CPU, so no world coordinate is ever a float) to the lasso's NDC,
// and there the lasso's mask decides: uMaskSize^2 bits over [-1, 1]^2, row 0 at NDC y = -1.
// Points and meshes alike, and any LOD: only the depth plane is read, and the pick ids: a
// selection tints only its own model's pixels (ids in [uPickFirst, uPickFirst + uPickCount)).
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = TESSERA_BINDING_DEPTH) readonly buffer Depth { uint depth[]; };
layout(std430, binding = TESSERA_BINDING_IMAGE) buffer Image { uint image[]; };
layout(std430, binding = TESSERA_BINDING_SCREEN_SCRATCH) readonly buffer Mask { uint mask[]; };
layout(std430, binding = TESSERA_BINDING_PICK) readonly buffer Pick { uint pick[]; };

uniform ivec2 uSize;
uniform mat4 uLassoFromNdc;
uniform uint uMaskSize;
uniform uint uPickFirst;  // the selected model's pick ids (uPickCount 0xFFFFFFFF: any)
uniform uint uPickCount;
uniform vec4 uTint;  // rgb, and alpha: how much of it replaces the pixel's colour

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint d = depth[uint(p.y) * uint(uSize.x) + uint(p.x)];
  if (d == 0xFFFFFFFFu) return;
  // Another model's pixel (or none: 0xFFFFFFFF), by unsigned wrap-around below uPickFirst.
  if (uPickCount != 0xFFFFFFFFu &&
      pick[uint(p.y) * uint(uSize.x) + uint(p.x)] - uPickFirst >= uPickCount)
    return;
  vec4 ndc = vec4((vec2(p) + 0.5) / vec2(uSize) * 2.0 - 1.0, uintBitsToFloat(d) * 2.0 - 1.0, 1.0);
  vec4 c = uLassoFromNdc * ndc;
  if (!(c.w > 0.0)) return;  // behind the lasso's eye
  vec2 q = c.xy / c.w;
  if (!(q.x >= -1.0 && q.x < 1.0 && q.y >= -1.0 && q.y < 1.0)) return;
  uvec2 m = min(uvec2((q * 0.5 + 0.5) * float(uMaskSize)), uvec2(uMaskSize - 1u));
  uint bit = m.y * uMaskSize + m.x;
  if ((mask[bit >> 5u] & (1u << (bit & 31u))) == 0u) return;
  uint out_index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
  vec4 was = unpackUnorm4x8(image[out_index]);
  image[out_index] = packUnorm4x8(vec4(mix(was.rgb, uTint.rgb, uTint.a), was.a));
}
