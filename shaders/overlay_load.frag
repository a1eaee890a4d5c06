// The overlay pass's first step: the frame target's image and depth into the overlay's
// framebuffer (row 0 = the image's top row), so overlay primitives blend over the scene and are
// depth-tested against it. Drawn as one full-screen triangle (overlay_fullscreen.vert).
layout(std430, binding = TESSERA_BINDING_DEPTH) readonly buffer Depth { uint depth[]; };  // raster order
layout(std430, binding = TESSERA_BINDING_IMAGE) readonly buffer Image { uint image[]; };  // top row first

uniform ivec2 uSize;

out vec4 fragColor;

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  uint rgba = image[uint(p.y) * uint(uSize.x) + uint(p.x)];
  fragColor = vec4(rgba & 0xFFu, (rgba >> 8) & 0xFFu, (rgba >> 16) & 0xFFu, rgba >> 24) / 255.0;
  uint d = depth[uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x)];
  gl_FragDepth = d == 0xFFFFFFFFu ? 1.0 : uintBitsToFloat(d);
}
