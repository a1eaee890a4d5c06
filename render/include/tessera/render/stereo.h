// Stereo pictures from one view: each eye's view through the same screen window (the wall plane,
// or for a plain view a zero-parallax plane at the camera target's distance), off-axis as the
// tiles of a wall are (Kooima's generalized perspective projection, tile_frustum.h), and the ways
// two eyes' pictures are put together for a file: side by side, top and bottom, a red-cyan
// anaglyph.
//
// A point on the screen plane lands on the same pixel in both eyes; a point at view distance Z
// from the eyes, with eye separation s and screen distance D, lands s (1 - D / Z) metres of the
// screen further right in the right eye than in the left (behind the screen: positive, in front:
// negative).
#pragma once

#include <string>

#include <tessera/render/image.h>
#include <tessera/render/tile_frustum.h>

namespace tessera::render {

/// How two eyes' pictures make one file.
enum class StereoLayout {
  kSideBySide,  ///< left eye on the left, right eye on the right: twice the width
  kTopBottom,   ///< left eye on top: twice the height
  kAnaglyph,    ///< red from the left eye, green and blue from the right (red-cyan glasses)
  kPair,        ///< two files, OUT-left.png and OUT-right.png
};

/// "sbs", "tb", "anaglyph", "pair"; anything else throws RenderError naming `what` and the text.
StereoLayout parseStereoLayout(const std::string& text, const std::string& what);

/// The view of an eye moved by `eye_offset` (in `mono`'s camera frame, metres, x right, y up;
/// z must be 0) looking through the same window as `mono` on the plane `screen_distance` metres
/// in front of the mono eye (the zero-parallax plane): the view matrix moved with the eye, the
/// projection sheared so that plane's points keep their pixels. For a wall view with
/// screen_distance the wall eye's distance (wall.eye().z) it is tileView() with that eye offset.
/// Precondition (TESSERA_CHECK): `mono.projection` is a perspective one, screen_distance > 0 and
/// finite, eye_offset.z == 0.
ViewSetup stereoEyeView(const ViewSetup& mono, const glm::dvec3& eye_offset,
                        double screen_distance);

/// The two eyes' pictures in one image (kSideBySide, kTopBottom, kAnaglyph). Precondition
/// (TESSERA_CHECK): both the same size, layout not kPair.
Image composeStereo(const Image& left, const Image& right, StereoLayout layout);

/// OUT.png's files for one eye: OUT-left.png or OUT-right.png (the extension kept).
std::string stereoPairPath(const std::string& path, bool right);

}  // namespace tessera::render
