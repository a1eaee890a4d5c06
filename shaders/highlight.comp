// The highlight pass (screen_passes.h): tints the pixels whose surface point, seen
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
// Visible-only selections: the window depth the lasso's view shows, uLassoSize over its NDC.
layout(std430, binding = TESSERA_BINDING_TARGET_DEPTH) readonly buffer LassoDepth { uint lasso_depth[]; };

uniform ivec2 uSize;
uniform mat4 uLassoFromNdc;
uniform uint uMaskSize;
uniform uint uPickFirst;  // the selected model's pick ids (uPickCount 0xFFFFFFFF: any)
uniform uint uPickCount;
uniform vec4 uTint;
uniform int uVisibleOnly;  // 1: tint only what the lasso's view did not see hidden
uniform ivec2 uLassoSize;
uniform float uLassoP22;   // the lasso projection's [2][2] and [3][2]: eye depth from window depth
uniform float uLassoP32;
uniform vec4 uWorldW;      // row 3 of this view's world-from-clip: the unprojected point's w

// The eye depth the lasso's view shows at its pixel l: its own, else (a gap between splats) the
// nearest of its 8 neighbours'; +infinity where nothing was drawn (nothing hides).
float lassoSurface(ivec2 l) {
  uint d = lasso_depth[uint(l.y) * uint(uLassoSize.x) + uint(l.x)];
  for (int k = 0; k < 9 && d == 0xFFFFFFFFu; ++k) {
    ivec2 q = l + ivec2(k % 3 - 1, k / 3 - 1);
    if (q.x >= 0 && q.y >= 0 && q.x < uLassoSize.x && q.y < uLassoSize.y)
      d = min(d, lasso_depth[uint(q.y) * uint(uLassoSize.x) + uint(q.x)]);
  }
  if (d == 0xFFFFFFFFu) return 1.0 / 0.0;
  return uLassoP32 / ((uintBitsToFloat(d) * 2.0 - 1.0) + uLassoP22);
}  // rgb, and alpha: how much of it replaces the pixel's colour

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
  // Visible only: hidden from the lasso's view behind a nearer surface (1%, as the lasso's own
  // VisibilityOptions): not tinted. c.w is the point's eye depth in the lasso's view.
  if (uVisibleOnly != 0) {
    ivec2 l = min(ivec2((q * 0.5 + 0.5) * vec2(uLassoSize)), uLassoSize - 1);
    // uLassoFromNdc takes the pixel to the lasso's clip space up to the unprojection's w.
    if (c.w / dot(uWorldW, ndc) > lassoSurface(l) * 1.01) return;
  }
  uint out_index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
  vec4 was = unpackUnorm4x8(image[out_index]);
  image[out_index] = packUnorm4x8(vec4(mix(was.rgb, uTint.rgb, uTint.a), was.a));
}
