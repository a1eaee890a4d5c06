// Overlay primitives' colour: flat, textured, a round dot or ring (antialiased edges) or a glyph
// (alpha from the font atlas). The mode's low byte says which; rings keep their inner radius
// (0..255 of the outer) in the next byte. World primitives are depth-tested here against the
// frame target's depth (a fragment behind the scene's nearest point is discarded, as LEQUAL),
// so the pass needs no depth attachment loaded per pixel of the view.
//
// Variants (render/src/overlay_pass.cpp compiles one per run's mix): HAS_TEXTURED, HAS_DOT,
// HAS_GLYPH say which modes beside flat the run holds, ONE_MODE that it holds one only,
// HAS_TESTED / HAS_UNTESTED whether some of its primitives are depth-tested / not. llvmpipe runs
// every branch under masks, so code a run does not need would cost all of its fragments.
#ifndef HAS_TEXTURED
#define HAS_TEXTURED 1
#define HAS_DOT 1
#define HAS_GLYPH 1
#define HAS_TESTED 1
#define HAS_UNTESTED 1
#define ONE_MODE 0
#endif
// WRITES_DEPTH: the run's opaque fragments (video insets) write their depth into the overlay's
// copy of the depth plane, so the lines, dots, labels and insets drawn after them are hidden
// behind them as behind the scene.
#ifndef WRITES_DEPTH
#define WRITES_DEPTH 0
#endif

#if WRITES_DEPTH
layout(std430, binding = TESSERA_BINDING_DEPTH) buffer Depth { uint depth[]; };  // raster order
#else
layout(std430, binding = TESSERA_BINDING_DEPTH) readonly buffer Depth { uint depth[]; };
#endif

uniform ivec2 uSize;
in vec2 vUv;
in vec4 vColor;
flat in uint vMode;

uniform sampler2D uTexture;

out vec4 fragColor;

void main() {
#if HAS_TESTED
#if HAS_UNTESTED
  if ((vMode & TESSERA_OVERLAY_DEPTH_TESTED) != 0u)
#endif
  {
    // Framebuffer row 0 is the image's top row; the depth plane is bottom row first.
    ivec2 p = ivec2(gl_FragCoord.xy);
    uint d = depth[uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x)];
    if (d != 0xFFFFFFFFu && gl_FragCoord.z > uintBitsToFloat(d)) discard;
  }
#endif
  vec4 c = vColor;
  uint mode = vMode & 0xFFu;
#if HAS_TEXTURED
  if (ONE_MODE != 0 || mode == TESSERA_OVERLAY_TEXTURED) c *= texture(uTexture, vUv);
#endif
#if HAS_DOT
  if (ONE_MODE != 0 || mode == TESSERA_OVERLAY_DOT) {
    float r = length(vUv * 2.0 - 1.0);
    float edge = max(fwidth(r), 1e-4);
    float hole = float((vMode >> 8) & 0xFFu) / 255.0;  // rings: the inner radius, 0 for a dot
    if (r > 1.0 || r < hole - edge) discard;
    c.a *= clamp((1.0 - r) / edge, 0.0, 1.0) * (hole > 0.0 ? clamp((r - hole) / edge, 0.0, 1.0) : 1.0);
  }
#endif
#if HAS_GLYPH
  if (ONE_MODE != 0 || mode == TESSERA_OVERLAY_GLYPH) c.a *= texture(uTexture, vUv).r;
#endif
#if WRITES_DEPTH
  if (c.a >= 0.999) {
    ivec2 q = ivec2(gl_FragCoord.xy);
    atomicMin(depth[uint(uSize.y - 1 - q.y) * uint(uSize.x) + uint(q.x)],
              floatBitsToUint(gl_FragCoord.z));
  }
#endif
  fragColor = c;
}
