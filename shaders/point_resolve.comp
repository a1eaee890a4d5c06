// Resolves the winning point of each pixel to its colour (background where none won), rows
// flipped so row 0 is the top of the image.
layout(local_size_x = 16, local_size_y = 16) in;

struct Point {
  vec3 position;
  uint rgba;
};
layout(std430, binding = 0) readonly buffer Points { Point points[]; };
layout(std430, binding = 2) readonly buffer Ids { uint ids[]; };
layout(std430, binding = 3) writeonly buffer Image { uint image[]; };

uniform ivec2 uSize;
uniform uint uBackground;  // rgba, r in the low byte

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= uSize.x || p.y >= uSize.y) return;
  uint id = ids[uint(p.y) * uint(uSize.x) + uint(p.x)];
  uint out_row = uint(uSize.y - 1 - p.y);
  image[out_row * uint(uSize.x) + uint(p.x)] = id == 0xFFFFFFFFu ? uBackground : (points[id].rgba | 0xFF000000u);
}
