// Overlay primitives' colour: flat, textured, a round dot or ring (antialiased edges) or a glyph
// (alpha from the font atlas). The mode's low byte says which; rings keep their inner radius
// (0..255 of the outer) in the next byte.
in vec2 vUv;
in vec4 vColor;
flat in uint vMode;

uniform sampler2D uTexture;

out vec4 fragColor;

void main() {
  vec4 c = vColor;
  uint mode = vMode & 0xFFu;
  if (mode == TESSERA_OVERLAY_TEXTURED) {
    c *= texture(uTexture, vUv);
  } else if (mode == TESSERA_OVERLAY_DOT) {
    float r = length(vUv * 2.0 - 1.0);
    float edge = max(fwidth(r), 1e-4);
    float hole = float(vMode >> 8) / 255.0;  // rings: the inner radius, 0 for a dot
    if (r > 1.0 || r < hole - edge) discard;
    c.a *= clamp((1.0 - r) / edge, 0.0, 1.0) * (hole > 0.0 ? clamp((r - hole) / edge, 0.0, 1.0) : 1.0);
  } else if (mode == TESSERA_OVERLAY_GLYPH) {
    c.a *= texture(uTexture, vUv).r;
  }
  fragColor = c;
}
