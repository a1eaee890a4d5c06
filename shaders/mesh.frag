// The mesh pass's fragments (render/mesh_pass.h): a headlight-shaded colour packed as the frame
// target keeps it (rgb, r in the low byte, top byte 0: a tie with a point at the same depth goes
// to the triangle) and the pick id (the batch's base + the triangle's index in its patch).
in vec3 vLocal;
in vec3 vNormal;
in vec4 vColor;

uniform vec3 uEyeLocal;
uniform uint uColorOverride;  // non-zero: 0x1000000 | rgb
uniform uint uPickBase;
uniform int uFlat;            // facet normals from the screen derivatives

layout(location = 0) out uint outColor;
layout(location = 1) out uint outPick;

void main() {
  vec3 n = uFlat != 0 ? cross(dFdx(vLocal), dFdy(vLocal)) : vNormal;
  float len = length(n);
  n = len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0);
  vec3 toEye = uEyeLocal - vLocal;
  float d = length(toEye);
  // Two-sided headlight: scans are open surfaces seen from both sides.
  float lambert = d > 0.0 ? abs(dot(n, toEye / d)) : 1.0;
  vec3 base = uColorOverride != 0u
                  ? vec3(uColorOverride & 0xFFu, (uColorOverride >> 8) & 0xFFu,
                         (uColorOverride >> 16) & 0xFFu) / 255.0
                  : vColor.rgb;
  vec3 c = clamp(base * (0.2 + 0.8 * lambert), 0.0, 1.0);
  uvec3 q = uvec3(c * 255.0 + 0.5);
  outColor = q.r | q.g << 8 | q.b << 16;
  outPick = uPickBase + uint(gl_PrimitiveID);
}
