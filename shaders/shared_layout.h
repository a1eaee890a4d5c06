// Buffer bindings and struct layouts shared by the C++ renderer (render/src/point_rasterizer.cpp)
// and every compute shader here (STYLE.md; niagara's config.h): C++ includes this file, and the
// render library puts it in front of each shader's source (after #version), so a binding or a
// layout is written once. GLSL's preprocessor takes the #defines; the GLSL structs are guarded
// by __cplusplus and their C++ twins static_assert the same sizes.
#ifndef TESSERA_SHADERS_SHARED_LAYOUT_H
#define TESSERA_SHADERS_SHARED_LAYOUT_H

// Shader storage buffer bindings.
#define TESSERA_BINDING_POINTS 0   // Point[]: the batch's points
#define TESSERA_BINDING_DEPTH 1    // uint per pixel (per layer, see-through): nearest depth
#define TESSERA_BINDING_COLORS 2   // uint per pixel (per layer): the nearest point's rgb
#define TESSERA_BINDING_IMAGE 3    // uint per pixel: the resolved RGBA8 image
#define TESSERA_BINDING_NORMALS 4  // uint per point: 10:10:10 snorm normal (slant shading)
#define TESSERA_BINDING_ACCUM 5    // see-through: r, g, b sums per pixel; OIT: 5 floats a pixel
#define TESSERA_BINDING_RATIOS 6   // float per point: node / local density (see-through)
#define TESSERA_BINDING_CELLS 7    // uvec2 per point: surface cell (sparse see-through)

// A point as the GPU reads it: 16 bytes, position relative to its batch's node box (metres,
// float), rgba with r in the low byte. C++: render::GpuPoint.
#define TESSERA_POINT_BYTES 16
#ifndef __cplusplus
struct Point {
  vec3 position;
  uint rgba;
};
#endif

#endif  // TESSERA_SHADERS_SHARED_LAYOUT_H
