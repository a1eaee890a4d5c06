// The mesh pass's vertices (render/mesh_pass.h): a patch's vertex in its store's local frame,
// its normal (10:10:10 snorm), colour and geomorphing target, to clip space with the batch's
// transform. Smooth shading is done here (a two-sided headlight per vertex, interpolated):
// triangles of scans are about a pixel, so per-vertex lighting looks the same and the fragments
// stay cheap. MESH_FLAT (the flat variant) passes the local position and the unlit colour on
// instead, and the fragment shader lights each fragment with its facet's normal.
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec4 aNormal;
layout(location = 2) in vec4 aColor;
layout(location = 3) in vec3 aMorph;        // the nearest point of the parent's surface
layout(location = 4) in vec4 aMorphNormal;  // the parent's normal there

uniform mat4 uClipFromLocal;
uniform vec3 uEyeLocal;
uniform uint uColorOverride;  // non-zero: 0x1000000 | rgb
uniform float uMorph;         // 0: on the parent's surface, 1: the patch's own shape

out vec3 vClipLocal;  // the position the clip planes test (patch frame)
#ifdef MESH_FLAT
out vec3 vLocal;
out vec3 vBase;   // unlit
#else
out vec3 vColor;  // lit
#endif

void main() {
  // Patches at their own shape (most of them) skip the morph (a uniform branch).
  bool morphing = uMorph < 1.0;
  vec3 position = morphing ? mix(aMorph, aPosition, uMorph) : aPosition;
  gl_Position = uClipFromLocal * vec4(position, 1.0);
  vClipLocal = position;
  vec3 base = uColorOverride != 0u
                  ? vec3(uColorOverride & 0xFFu, (uColorOverride >> 8) & 0xFFu,
                         (uColorOverride >> 16) & 0xFFu) / 255.0
                  : aColor.rgb;
#ifdef MESH_FLAT
  vLocal = position;
  vBase = base;
#else
  vec3 n = morphing ? mix(aMorphNormal.xyz, aNormal.xyz, uMorph) : aNormal.xyz;
  vec3 toEye = uEyeLocal - position;
  // Two-sided headlight: |cos| of the normal and the direction to the eye.
  float nn = dot(n, n) * dot(toEye, toEye);
  float lambert = nn > 0.0 ? abs(dot(n, toEye)) * inversesqrt(nn) : 1.0;
  vColor = base * (0.2 + 0.8 * lambert);
#endif
}
