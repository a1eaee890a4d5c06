// Overlay primitives (render/src/overlay_pass.cpp): triangles the CPU has already projected to
// clip space (double precision, y flipped so framebuffer row 0 is the image's top row), read by
// gl_VertexID from one buffer.
layout(std430, binding = TESSERA_BINDING_OVERLAY) readonly buffer Vertices { OverlayVertex vertices[]; };
// Labels are shown or hidden whole by their anchor: the anchor's pixel (x, y), its distance
// (perspective: the eye distance, clip w; orthographic: NDC z) and whether the view is a
// perspective one. Hidden when the scene at that pixel lies in front of the anchor by more than
// 2% of its distance (perspective) or 0.02 in NDC depth: anchors sit on the surface the splats
// cover (a measurement's middle on a chord just under it). Done here, per vertex, so no label
// waits for a read-back of the depth on the CPU.
layout(std430, binding = TESSERA_BINDING_OVERLAY_ANCHORS) readonly buffer Anchors { vec4 anchors[]; };
// As overlay.frag declares it (insets' runs write it there: WRITES_DEPTH).
#ifndef WRITES_DEPTH
#define WRITES_DEPTH 0
#endif
#if WRITES_DEPTH
layout(std430, binding = TESSERA_BINDING_DEPTH) buffer Depth { uint depth[]; };  // raster order
#else
layout(std430, binding = TESSERA_BINDING_DEPTH) readonly buffer Depth { uint depth[]; };
#endif

uniform ivec2 uSize;
uniform vec2 uDepthFromNdc;  // perspective: eye distance = uDepthFromNdc.x / (ndc + uDepthFromNdc.y)

out vec2 vUv;
out vec4 vColor;
flat out uint vMode;

bool anchorHidden(vec4 a) {
  ivec2 p = ivec2(a.xy);
  if (p.x < 0 || p.y < 0 || p.x >= uSize.x || p.y >= uSize.y) return false;
  uint d = depth[uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x)];
  if (d == 0xFFFFFFFFu) return false;
  float ndc = 2.0 * uintBitsToFloat(d) - 1.0;
  if (a.w != 0.0) return a.z > 1.02 * abs(uDepthFromNdc.x / (ndc + uDepthFromNdc.y));
  return a.z > ndc + 0.02;
}

void main() {
  OverlayVertex v = vertices[gl_VertexID];
  gl_Position = v.clip;
  if ((v.mode & TESSERA_OVERLAY_ANCHORED) != 0u &&
      anchorHidden(anchors[v.mode >> TESSERA_OVERLAY_ANCHOR_SHIFT]))
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // outside the view: the label's triangles vanish
  vUv = v.uv;
  vColor = vec4(v.rgba & 0xFFu, (v.rgba >> 8) & 0xFFu, (v.rgba >> 16) & 0xFFu, v.rgba >> 24) / 255.0;
  vMode = v.mode;
}
