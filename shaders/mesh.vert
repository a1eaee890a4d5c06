// The mesh pass's vertices (render/mesh_pass.h): a patch's vertex in its store's local frame,
// its normal (10:10:10 snorm) and colour, to clip space with the batch's transform. Smooth
// shading is done here (a two-sided headlight per vertex, interpolated): triangles of scans
// are about a pixel, so per-vertex lighting looks the same and keeps fragments cheap.
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec4 aNormal;
layout(location = 2) in vec4 aColor;
layout(location = 3) in vec3 aMorph;        // the nearest point of the parent's surface
layout(location = 4) in vec4 aMorphNormal;  // the parent's normal there

uniform mat4 uClipFromLocal;
uniform vec3 uEyeLocal;
uniform uint uColorOverride;  // non-zero: 0x1000000 | rgb
uniform float uMorph;         // 0: on the parent's surface, 1: the patch's own shape

out vec3 vLocal;
out vec3 vBase;   // the unlit colour (flat shading lights it per fragment)
out vec3 vColor;  // lit (smooth shading)

void main() {
  vec3 position = mix(aMorph, aPosition, uMorph);
  gl_Position = uClipFromLocal * vec4(position, 1.0);
  vLocal = position;
  vBase = uColorOverride != 0u
              ? vec3(uColorOverride & 0xFFu, (uColorOverride >> 8) & 0xFFu,
                     (uColorOverride >> 16) & 0xFFu) / 255.0
              : aColor.rgb;
  vec3 n = mix(aMorphNormal.xyz, aNormal.xyz, uMorph);
  float len = length(n);
  vec3 toEye = uEyeLocal - position;
  float d = length(toEye);
  // Two-sided headlight: scans are open surfaces seen from both sides.
  float lambert = len > 0.0 && d > 0.0 ? abs(dot(n / len, toEye / d)) : 1.0;
  vColor = vBase * (0.2 + 0.8 * lambert);
}
