// Overlay primitives (render/src/overlay_pass.cpp): triangles the CPU has already projected to
// clip space (double precision, y flipped so framebuffer row 0 is the image's top row), read by
// gl_VertexID from one buffer.
layout(std430, binding = TESSERA_BINDING_OVERLAY) readonly buffer Vertices { OverlayVertex vertices[]; };

out vec2 vUv;
out vec4 vColor;
flat out uint vMode;

void main() {
  OverlayVertex v = vertices[gl_VertexID];
  gl_Position = v.clip;
  vUv = v.uv;
  vColor = vec4(v.rgba & 0xFFu, (v.rgba >> 8) & 0xFFu, (v.rgba >> 16) & 0xFFu, v.rgba >> 24) / 255.0;
  vMode = v.mode;
}
