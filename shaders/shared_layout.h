// Buffer bindings and struct layouts shared by the C++ renderer (render/src/*_pass.cpp)
// and every compute shader here (niagara's config.h): C++ includes this file, and the
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
#define TESSERA_BINDING_ACCUM 5    // see-through: r, g, b sums per pixel; OIT: 5 floats a pixel
#define TESSERA_BINDING_PICK 8     // uint per pixel: the nearest element's frame-wide pick id
#define TESSERA_BINDING_TARGET_DEPTH 9  // the frame target's depth (see-through: nearest copy)
#define TESSERA_BINDING_OVERLAY 10      // overlay primitives (overlay_pass.h)
#define TESSERA_BINDING_COLOR_SUMS 11   // uvec4 per pixel: weighted r, g, b sums and weight
#define TESSERA_BINDING_SCREEN_SCRATCH 12  // float per pixel: a screen pass's own plane (EDL)
#define TESSERA_BINDING_SPLAT_FOOTPRINTS 13  // uvec2 per pixel: the nearest point's splat (fill)
#define TESSERA_BINDING_FILL_DEPTH 15      // the fill's output planes: depth, colours, pick ids
#define TESSERA_BINDING_FILL_COLORS 16
#define TESSERA_BINDING_FILL_PICK 17
#define TESSERA_BINDING_FILL_TILE_MARKS 14  // uint per fill tile: holds a drawn pixel
#define TESSERA_BINDING_OVERLAY_ANCHORS 18  // vec4 per label: its anchor (overlay.vert)
#define TESSERA_BINDING_OVERLAY_LINES 19    // OverlayLine[]: opaque lines (overlay_lines.comp)
#define TESSERA_BINDING_OVERLAY_OWNER 20    // uint per pixel: the last line covering it, + 1
#define TESSERA_BINDING_OVERLAY_STEPS 21    // uint per step along the lines: its line
#define TESSERA_BINDING_ANALYSIS_PLANE 22   // float per pixel: relative depth (analysis.comp)
#define TESSERA_BINDING_ANALYSIS_RANGE 23   // its extremes (ordered float bits), histogram
#define TESSERA_ANALYSIS_BINS 4096u         // the relative depth's histogram (its percentiles)
#define TESSERA_ANALYSIS_MAX_TAPS 32        // the relative depth blur's taps a pass, at most

// The pull-push fill (shaders/fill.comp, FillPass): most pyramid levels above the frame (reach
// 2^levels pixels); its pyramid's texture units (samples, the push's winners) and image units
// (the level written, level 0's samples).
#define TESSERA_FILL_MAX_LEVELS 4
#define TESSERA_FILL_TILE 16  // the fill works in tiles of 2^TESSERA_FILL_MAX_LEVELS pixels
#ifndef __cplusplus
// The group of points as near as the nearest that a pixel's splat footprint is chosen among
// (point_raster.comp writes it, fill.comp reads it): the top 14 bits of 1 - window depth `d`
// (exponent and 5 bits of mantissa), the larger the nearer; 0 for none (0xFFFFFFFF). Under a
// perspective projection 1 - window depth falls as 1 / view depth, so a group is 1.6-3.2% of
// the view depth wide wherever it is (1.0 - x is exact for window depths above 1/2). The top
// bits of the window depth itself held most of a model at once (window depth crowds towards 1
// with the distance), so every point of the 10^7-point cube took the footprint's atomics;
// narrower groups (16 bits) split more of a surface's points at a group's edge, whose pixels
// then lose the grown disc of several points (bench/fill: the bunny scan's open pixels 0.0044%
// at 12 bits, 0.016% at 14, 0.027% at 16).
uint tesseraFillGroup(uint d) {
  return d == 0xFFFFFFFFu ? 0u : floatBitsToUint(1.0 - uintBitsToFloat(d)) & 0xFFFC0000u;
}
#endif
#define TESSERA_TEXTURE_FILL_SAMPLES 0
#define TESSERA_TEXTURE_FILL_WINNERS 1
#define TESSERA_IMAGE_FILL_OUT 0
#define TESSERA_IMAGE_FILL_LEVEL0 1

// Texture units of buffer views (GlBufferTexture): the frame's planes, a screen pass's own plane
// (EDL's denoised depth), the points of a batch (point_raster.comp).
#define TESSERA_TEXTURE_DEPTH 2
#define TESSERA_TEXTURE_SCREEN_SCRATCH 3
#define TESSERA_TEXTURE_POINTS 4
#define TESSERA_TEXTURE_COLORS 5
#define TESSERA_TEXTURE_PICK 6
#define TESSERA_TEXTURE_FOOTPRINTS 7
#define TESSERA_TEXTURE_FILL_TILES 8  // the fill's list of tiles
// See-through (spbr_raster.comp): each point's normal, density ratio and surface cell.
#define TESSERA_TEXTURE_SPBR_NORMALS 9
#define TESSERA_TEXTURE_SPBR_RATIOS 10
#define TESSERA_TEXTURE_SPBR_CELLS 11
#define TESSERA_TEXTURE_COLOR_SUMS 12  // blended points' sums (resolve.comp)

// Eye-dome lighting (shaders/edl.comp, EdlOptions::filter_radius): the largest fitted window's
// half-width, pixels.
#define TESSERA_EDL_MAX_FILTER_RADIUS 4

// Clip planes (render/clip_planes.h, the scene's CLIP nodes): most planes cutting one
// model. The geometry passes (point_raster, spbr_raster, oit_accumulate, mesh) test each point
// or fragment in its batch's frame with tesseraClipped(); a program that never sets uClipCount
// clips nothing. Planes are unit-normal floats in that frame (made in double on the CPU).
#define TESSERA_MAX_CLIP_PLANES 12
#ifndef __cplusplus
// uClipPlanes: a b c d, inside where a x + b y + c z + d >= 0; uClipGroups: each plane's group
// (one per CLIP node).
uniform vec4 uClipPlanes[TESSERA_MAX_CLIP_PLANES];
uniform uint uClipGroups[TESSERA_MAX_CLIP_PLANES];
uniform uint uClipCount;   // planes used
uniform uint uClipInvert;  // bit g: group g keeps its outside
// Whether a cut removes position p: group g keeps p where p is inside all its planes (outside
// one of them, with bit g of uClipInvert); p is drawn when every group keeps it. The same rule
// as render::ClipPlanes::keeps().
// A program compiled with TESSERA_CLIPPING 0 (for batches without planes) clips nothing and
// has no plane code at all: on llvmpipe the test cost a one-pixel point pass as much as its
// scatter even with uClipCount 0 (bench/render_points: 186 ms against 87 ms a pass for 10^7
// points).
#ifndef TESSERA_CLIPPING
#define TESSERA_CLIPPING 1
#endif
bool tesseraClipped(vec3 p) {
#if !TESSERA_CLIPPING
  return false;
#endif
  if (uClipCount == 0u) return false;
  uint present = 0u, outside = 0u;
  for (uint i = 0u; i < uClipCount; ++i) {
    uint bit = 1u << uClipGroups[i];
    present |= bit;
    if (dot(uClipPlanes[i].xyz, p) + uClipPlanes[i].w < 0.0) outside |= bit;
  }
  uint kept = (present & ~outside & ~uClipInvert) | (outside & uClipInvert);
  return kept != present;
}
#endif

// A point as the GPU reads it: 16 bytes, position relative to its batch's node box (metres,
// float), rgba with r in the low byte. C++: render::GpuPoint.
#define TESSERA_POINT_BYTES 16
#ifndef __cplusplus
struct Point {
  vec3 position;
  uint rgba;
};
#endif

// An overlay vertex (overlay_pass.h): clip position computed on the CPU, texture coordinates,
// rgba (r in the low byte), and how the fragment is coloured. 32 bytes.
// C++: render::OverlayVertex (render/src/overlay_pass.cpp).
#define TESSERA_OVERLAY_FLAT 0u      // the vertex colour
#define TESSERA_OVERLAY_TEXTURED 1u  // colour x texture
#define TESSERA_OVERLAY_DOT 2u       // a round dot (or ring) inscribed in the quad (uv 0..1)
#define TESSERA_OVERLAY_GLYPH 3u     // colour, alpha x the font atlas's coverage
// Above the mode's low byte (and a ring's inner radius in the next): flags.
#define TESSERA_OVERLAY_DEPTH_TESTED (1u << 16)  // hidden behind the scene's nearest surface
#define TESSERA_OVERLAY_ANCHORED (1u << 17)      // shown whole or hidden by its anchor (labels)
#define TESSERA_OVERLAY_ANCHOR_SHIFT 18u         // the anchor's index (0..16383) above the flags
#define TESSERA_OVERLAY_MAX_ANCHORS 16384u
#define TESSERA_OVERLAY_VERTEX_BYTES 32
#ifndef __cplusplus
struct OverlayVertex {
  vec4 clip;
  vec2 uv;
  uint rgba;
  uint mode;
};
#endif

// An opaque overlay line drawn by shaders/overlay_lines.comp: its ends in pixels (x right, y
// down from the image's top), its window depth (as gl_FragCoord.z) at the first end and its
// change per pixel along the line, its half width in pixels, whether it is depth-tested, and
// its rgb (r in the low byte); its steps (columns if x-major, else rows, `first` the first on
// screen) are numbered from `base` among all lines'. 48 bytes.
// C++: render::GpuOverlayLine (render/src/overlay_pass.cpp).
#define TESSERA_OVERLAY_LINE_BYTES 48
#ifndef __cplusplus
struct OverlayLine {
  vec4 ends;      // a.x, a.y, b.x, b.y
  vec4 depth;     // depth at a, its change per pixel towards b, half width, depth-tested (0/1)
  uint rgb;
  uint base;   // the line's first step among all lines'
  int first;   // its first column or row on screen
  uint flags;  // bit 0: x-major (steps are columns)
};
#endif

#endif  // TESSERA_SHADERS_SHARED_LAYOUT_H
