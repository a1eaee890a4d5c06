// The mesh pass's fragments (render/mesh_pass.h): the colour packed as the frame target keeps
// it (rgb, r in the low byte, top byte 0: a tie with a point at the same depth goes to the
// triangle) and the pick id (the batch's base + the triangle's index in its patch). The flat
// variant (MESH_FLAT) lights each fragment with the facet normal from the screen derivatives.
// Clip planes (shaders/shared_layout.h) discard fragments per pixel, exactly where the cut is.
#ifdef MESH_FLAT
in vec3 vLocal;
in vec3 vBase;
uniform vec3 uEyeLocal;
#else
in vec3 vColor;
#endif

uniform uint uPickBase;
in vec3 vClipLocal;

layout(location = 0) out uint outColor;
layout(location = 1) out uint outPick;

void main() {
#ifdef MESH_FLAT
  vec3 n = cross(dFdx(vLocal), dFdy(vLocal));
  vec3 toEye = uEyeLocal - vLocal;
  float nn = dot(n, n) * dot(toEye, toEye);
  vec3 c = vBase * (0.2 + 0.8 * (nn > 0.0 ? abs(dot(n, toEye)) * inversesqrt(nn) : 1.0));
#else
  vec3 c = vColor;
#endif
  // Cut away by a CLIP node: no depth, so what lies behind shows (and is picked). After the
  // derivatives above, which need the whole quad.
  if (tesseraClipped(vClipLocal)) discard;
  uvec3 q = uvec3(clamp(c, 0.0, 1.0) * 255.0 + 0.5);
  outColor = q.r | q.g << 8 | q.b << 16;
  outPick = uPickBase + uint(gl_PrimitiveID);
}
