// The keyboard of the wall's console and of a site's window: one map from keys to commands and
// one tool state machine, so a key means the same on the wall and at every site. Window-free:
// keys arrive as GLFW key codes (glfw3.h values, so no GLFW header is needed here), the front
// end does what a command asks, and a test drives the state machine with commands.
//
//   L lead the view          R release it            F follow the leader   P picture
//   U undo the newest sketch C clear my sketches     K section clip        O open the nearest note
//   A add a note             M measure (distance, path, angle, area, off)  S lasso   N snap
//   Enter end (a path, an area, a snap)   Backspace drop the last point, stroke or selection
//   1..9 the current model   + / - its opacity       H hide or show it     E eye-dome lighting
//   G ambient occlusion      D relative depth        T contour lines
//
// Which commands a front end offers is its own (a site has no section clip, the console does
// not follow); a key it does not offer does nothing.
#pragma once

#include <optional>
#include <span>
#include <string>

#include <tessera/scene.pb.h>

#include <tessera/interact/measure_tool.h>

namespace tessera::interact {

enum class Command {
  kNone,
  kLead,
  kRelease,
  kFollow,
  kPicture,
  kUndoSketch,
  kClearSketches,
  kClip,
  kOpenNote,
  kAddNote,
  kMeasure,
  kLasso,
  kSnap,
  kEnd,
  kBack,
  kModel,  ///< 1..9: KeyPress::model is 0..8
  kOpacityUp,
  kOpacityDown,
  kHide,
  kShading,
  kRelativeDepth,
  kContours,
  kAmbientOcclusion,
};

struct KeyPress {
  Command command = Command::kNone;
  int model = 0;  ///< kModel: which model, from 0
};

/// What GLFW key code `key` asks for (kNone for any other key).
KeyPress commandOf(int key);

/// "L lead, R release, ..." for the commands a front end offers, in the order given.
std::string keysHelp(std::span<const Command> offered);

/// What a shading key does to the scene's settings: E switches eye-dome lighting and colour; G
/// ambient occlusion (strength 1, 32 px), D relative depth (a 24 px blur), T contour lines of the
/// view depth every `contour_interval` metres, each on or off, the other filters kept.
struct SettingsEdit {
  scene::Settings delta;  ///< `shading` or the whole `analysis`
  std::string said;       ///< "ambient occlusion on", ...
};
/// The edit of `command` on `current` (nullopt for a command that is not a shading key). The
/// console applies it; a site sends it to the master, which applies it on every tile.
std::optional<SettingsEdit> shadingEdit(Command command, const scene::Settings& current,
                                        double contour_interval);

/// A round contour interval (1, 2 or 5 times a power of ten) near a 25th of `extent` (metres; 1
/// when it is not positive and finite).
double roundContourInterval(double extent);

/// One tool at a time: a tool key switches its tool on (and every other off), or off when it is
/// the one on. M steps distance -> path -> angle -> area -> off.
class ToolKeys {
 public:
  enum class Tool { kNone, kNote, kMeasure, kLasso, kSnap };

  Tool tool() const { return mTool; }
  /// The measuring mode: kOff unless the tool is kMeasure.
  MeasureTool::Mode measureMode() const {
    return mTool == Tool::kMeasure ? mMeasure : MeasureTool::Mode::kOff;
  }

  /// A tool command (kAddNote, kMeasure, kLasso, kSnap): the state changes and the line the user
  /// reads is returned. Any other command changes nothing and returns "".
  std::string press(Command command);
  /// Chooses directly (a panel's button): `mode` is the measuring mode for kMeasure (kOff: off).
  void choose(Tool tool, MeasureTool::Mode mode = MeasureTool::Mode::kDistance);

 private:
  Tool mTool = Tool::kNone;
  MeasureTool::Mode mMeasure = MeasureTool::Mode::kOff;
};

}  // namespace tessera::interact
