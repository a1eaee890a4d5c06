// One triangle covering the viewport (vertex ids 0, 1, 2).
void main() {
  vec2 p = vec2((gl_VertexID & 1) * 4 - 1, (gl_VertexID >> 1) * 4 - 1);
  gl_Position = vec4(p, 0.0, 1.0);
}
