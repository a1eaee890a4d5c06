// The mesh pass's vertices (render/mesh_pass.h): a patch's vertex in its store's local frame,
// its normal (10:10:10 snorm) and colour, to clip space with the batch's transform.
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec4 aNormal;
layout(location = 2) in vec4 aColor;

uniform mat4 uClipFromLocal;

out vec3 vLocal;
out vec3 vNormal;
out vec4 vColor;

void main() {
  gl_Position = uClipFromLocal * vec4(aPosition, 1.0);
  vLocal = aPosition;
  vNormal = aNormal.xyz;
  vColor = aColor;
}
