// Overlay primitives' colour: flat, textured, a round dot (antialiased edge) or a glyph (alpha
// from the font atlas).
in vec2 vUv;
in vec4 vColor;
flat in uint vMode;

uniform sampler2D uTexture;

out vec4 fragColor;

void main() {
  vec4 c = vColor;
  if (vMode == TESSERA_OVERLAY_TEXTURED) {
    c *= texture(uTexture, vUv);
  } else if (vMode == TESSERA_OVERLAY_DOT) {
    float r = length(vUv * 2.0 - 1.0);
    float edge = max(fwidth(r), 1e-4);
    if (r > 1.0) discard;
    c.a *= clamp((1.0 - r) / edge, 0.0, 1.0);
  } else if (vMode == TESSERA_OVERLAY_GLYPH) {
    c.a *= texture(uTexture, vUv).r;
  }
  fragColor = c;
}
