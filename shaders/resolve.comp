// The resolve pass: each pixel's nearest colour (or its blended points' weighted mean, or the
// one colour of the frame, or the background where nothing was drawn) into the image, rows flipped so row 0 is the top.
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = TESSERA_BINDING_DEPTH) readonly buffer Depth { uint depth[]; };
layout(std430, binding = TESSERA_BINDING_COLORS) readonly buffer Colors { uint colors[]; };  // rgb of the winner
layout(std430, binding = TESSERA_BINDING_IMAGE) writeonly buffer Image { uint image[]; };
layout(std430, binding = TESSERA_BINDING_COLOR_SUMS) readonly buffer Sums { uint sums[]; };

uniform ivec2 uSize;
uniform uint uBackground;    // rgba, r in the low byte
uniform uint uUniformColor;  // non-zero: every point has this colour and no colour pass ran
uniform int uBlended;        // colours are the weighted sums' means (blended points)

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint pixel = uint(p.y) * uint(uSize.x) + uint(p.x);
  uint out_index = uint(uSize.y - 1 - p.y) * uint(uSize.x) + uint(p.x);
  if (depth[pixel] == 0xFFFFFFFFu) {
    image[out_index] = uBackground;
    return;
  }
  if (uBlended != 0 && uUniformColor == 0u) {
    uvec4 s = uvec4(sums[pixel * 4u], sums[pixel * 4u + 1u], sums[pixel * 4u + 2u],
                    sums[pixel * 4u + 3u]);
    uvec3 c = (s.rgb + s.a / 2u) / max(s.a, 1u);
    image[out_index] = c.r | (c.g << 8) | (c.b << 16) | 0xFF000000u;
    return;
  }
  // colors[] holds a tie-break key in its top byte (point_raster.comp).
  image[out_index] = (uUniformColor != 0u ? uUniformColor : colors[pixel] & 0xFFFFFFu) | 0xFF000000u;
}
