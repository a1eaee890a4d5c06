#include <tessera/interact/keys.h>

#include <cmath>
#include <cstdio>

namespace tessera::interact {

namespace {

// GLFW key codes (glfw3.h).
constexpr int kKey1 = 49, kKey9 = 57, kKeyEqual = 61, kKeyMinus = 45, kKeyA = 65, kKeyC = 67,
              kKeyD = 68, kKeyG = 71, kKeyT = 84, kKeyE = 69, kKeyF = 70, kKeyH = 72, kKeyK = 75, kKeyL = 76, kKeyM = 77, kKeyN = 78,
              kKeyO = 79, kKeyP = 80, kKeyR = 82, kKeyS = 83, kKeyU = 85, kKeyEnter = 257,
              kKeyBackspace = 259, kKeyPadSubtract = 333, kKeyPadAdd = 334, kKeyPadEnter = 335;

const char* helpOf(Command c) {
  switch (c) {
    case Command::kLead: return "L lead";
    case Command::kRelease: return "R release";
    case Command::kFollow: return "F follow";
    case Command::kPicture: return "P picture";
    case Command::kUndoSketch: return "U undo";
    case Command::kClearSketches: return "C clear";
    case Command::kClip: return "K clip";
    case Command::kOpenNote: return "O open note";
    case Command::kAddNote: return "A add note";
    case Command::kMeasure: return "M measure";
    case Command::kLasso: return "S lasso";
    case Command::kSnap: return "N snap";
    case Command::kEnd: return "Enter end";
    case Command::kBack: return "Backspace back";
    case Command::kModel: return "1-9 model";
    case Command::kOpacityUp: return "+ opaque";
    case Command::kOpacityDown: return "- see-through";
    case Command::kHide: return "H hide";
    case Command::kShading: return "E lighting";
    case Command::kRelativeDepth: return "D relative depth";
    case Command::kContours: return "T contour lines";
    case Command::kAmbientOcclusion: return "G ambient occlusion";
    case Command::kNone: break;
  }
  return "";
}

}  // namespace

KeyPress commandOf(int key) {
  if (key >= kKey1 && key <= kKey9) return {Command::kModel, key - kKey1};
  switch (key) {
    case kKeyL: return {Command::kLead};
    case kKeyR: return {Command::kRelease};
    case kKeyF: return {Command::kFollow};
    case kKeyP: return {Command::kPicture};
    case kKeyU: return {Command::kUndoSketch};
    case kKeyC: return {Command::kClearSketches};
    case kKeyK: return {Command::kClip};
    case kKeyO: return {Command::kOpenNote};
    case kKeyA: return {Command::kAddNote};
    case kKeyM: return {Command::kMeasure};
    case kKeyS: return {Command::kLasso};
    case kKeyN: return {Command::kSnap};
    case kKeyEnter:
    case kKeyPadEnter: return {Command::kEnd};
    case kKeyBackspace: return {Command::kBack};
    case kKeyEqual:
    case kKeyPadAdd: return {Command::kOpacityUp};
    case kKeyMinus:
    case kKeyPadSubtract: return {Command::kOpacityDown};
    case kKeyH: return {Command::kHide};
    case kKeyE: return {Command::kShading};
    case kKeyD: return {Command::kRelativeDepth};
    case kKeyT: return {Command::kContours};
    case kKeyG: return {Command::kAmbientOcclusion};
    default: return {};
  }
}

std::optional<SettingsEdit> shadingEdit(Command command, const scene::Settings& current,
                                        double contour_interval) {
  SettingsEdit e;
  scene::Analysis a = current.analysis();
  switch (command) {
    case Command::kShading: {
      const bool edl = current.shading() != scene::SHADING_EDL;
      e.delta.set_shading(edl ? scene::SHADING_EDL : scene::SHADING_COLOR);
      e.said = edl ? "eye-dome lighting on" : "eye-dome lighting off";
      return e;
    }
    case Command::kAmbientOcclusion:
      a.set_ao_strength(a.ao_strength() > 0.0f ? 0.0f : 1.0f);
      e.said = a.ao_strength() > 0.0f ? "ambient occlusion on" : "ambient occlusion off";
      break;
    case Command::kRelativeDepth: {
      const bool on = a.relative_depth_radius() == 0 && !(a.relative_depth_radius_m() > 0.0f);
      a.set_relative_depth_radius(on ? 24 : 0);
      a.clear_relative_depth_radius_m();
      e.said = on ? "relative depth on" : "relative depth off";
      break;
    }
    case Command::kContours: {
      a.set_contour_interval(a.contour_interval() > 0.0 ? 0.0 : contour_interval);
      char line[96];
      std::snprintf(line, sizeof line, "contour lines every %g m", a.contour_interval());
      e.said = a.contour_interval() > 0.0 ? line : "contour lines off";
      break;
    }
    default:
      return std::nullopt;
  }
  *e.delta.mutable_analysis() = a;
  return e;
}

double roundContourInterval(double extent) {
  if (!(extent > 0.0) || !std::isfinite(extent)) return 1.0;
  const double raw = extent / 25.0, p = std::pow(10.0, std::floor(std::log10(raw)));
  return raw / p < 2.0 ? p : raw / p < 5.0 ? 2.0 * p : 5.0 * p;
}

std::string keysHelp(std::span<const Command> offered) {
  std::string out;
  for (Command c : offered) {
    if (!out.empty()) out += ", ";
    out += helpOf(c);
  }
  return out;
}

std::string ToolKeys::press(Command command) {
  using Mode = MeasureTool::Mode;
  switch (command) {
    case Command::kAddNote:
      if (mTool == Tool::kNote) {
        mTool = Tool::kNone;
        return "add note: cancelled";
      }
      mTool = Tool::kNote;
      return "add note: click on the model where it goes";
    case Command::kMeasure: {
      const Mode next = mTool != Tool::kMeasure     ? Mode::kDistance
                        : mMeasure == Mode::kDistance ? Mode::kPath
                        : mMeasure == Mode::kPath     ? Mode::kAngle
                        : mMeasure == Mode::kAngle    ? Mode::kArea
                                                      : Mode::kOff;
      choose(Tool::kMeasure, next);
      if (next == Mode::kOff) return "measuring off";
      return std::string("measuring: ") + MeasureTool::name(next) +
             (next == Mode::kPath || next == Mode::kArea
                  ? " (click points, Enter ends, Backspace drops the last)"
                  : " (click points)");
    }
    case Command::kLasso:
      if (mTool == Tool::kLasso) {
        mTool = Tool::kNone;
        return "lasso off";
      }
      mTool = Tool::kLasso;
      return "lasso on (drag around a region; Backspace removes the newest selection)";
    case Command::kSnap:
      if (mTool == Tool::kSnap) {
        mTool = Tool::kNone;
        return "snap off";
      }
      mTool = Tool::kSnap;
      return "snap on (left drag: what to select, right drag: what not to; Enter selects; "
             "Backspace drops the strokes)";
    default:
      return "";
  }
}

void ToolKeys::choose(Tool tool, MeasureTool::Mode mode) {
  if (tool == Tool::kMeasure && mode == MeasureTool::Mode::kOff) tool = Tool::kNone;
  mTool = tool;
  mMeasure = tool == Tool::kMeasure ? mode : MeasureTool::Mode::kOff;
}

}  // namespace tessera::interact
