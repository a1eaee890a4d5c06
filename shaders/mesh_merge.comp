// The mesh pass's second step (render/mesh_pass.h): the triangles' nearest depth, colour and
// pick id, rasterised by GL into the pass's framebuffer, written into the frame target's planes
// where a triangle covers the pixel. The point pass then depth-tests against them (its atomicMin
// on the same window-depth bits), so points and meshes hide each other in one picture.
layout(local_size_x = 8, local_size_y = 8) in;

layout(std430, binding = TESSERA_BINDING_DEPTH) buffer Depth { uint depth[]; };
layout(std430, binding = TESSERA_BINDING_COLORS) buffer Colors { uint colors[]; };
layout(std430, binding = TESSERA_BINDING_PICK) buffer Pick { uint pick[]; };

layout(binding = 0) uniform sampler2D uDepth;
layout(binding = 1) uniform usampler2D uColor;
layout(binding = 2) uniform usampler2D uPick;
uniform ivec2 uSize;
uniform int uWritePick;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  float d = texelFetch(uDepth, p, 0).r;
  if (d >= 1.0) return;  // no triangle
  // Both planes are bottom row first (GL's window order).
  uint i = uint(p.y) * uint(uSize.x) + uint(p.x);
  uint bits = floatBitsToUint(d);
  if (bits >= depth[i]) return;  // something nearer is already there
  depth[i] = bits;
  colors[i] = texelFetch(uColor, p, 0).r;
  if (uWritePick != 0) pick[i] = texelFetch(uPick, p, 0).r;
}
