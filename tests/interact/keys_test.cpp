// The keyboard the console and the sites share: the key map and the tool state machine.
#include <gtest/gtest.h>

#include <cmath>

#include <tessera/interact/keys.h>

namespace {

using tessera::interact::Command;
using tessera::interact::commandOf;
using tessera::interact::MeasureTool;
using tessera::interact::ToolKeys;
using Tool = ToolKeys::Tool;
using Mode = MeasureTool::Mode;

TEST(Keys, GlfwCodesMapToOneCommandEach) {
  EXPECT_EQ(commandOf(76).command, Command::kLead);  // L
  EXPECT_EQ(commandOf(82).command, Command::kRelease);
  EXPECT_EQ(commandOf(77).command, Command::kMeasure);
  EXPECT_EQ(commandOf(257).command, Command::kEnd);  // Enter and the keypad's
  EXPECT_EQ(commandOf(335).command, Command::kEnd);
  EXPECT_EQ(commandOf(259).command, Command::kBack);
  EXPECT_EQ(commandOf(61).command, Command::kOpacityUp);  // = and keypad +
  EXPECT_EQ(commandOf(334).command, Command::kOpacityUp);
  EXPECT_EQ(commandOf(49).command, Command::kModel);
  EXPECT_EQ(commandOf(49).model, 0);
  EXPECT_EQ(commandOf(57).model, 8);
  EXPECT_EQ(commandOf(48).command, Command::kNone);  // 0 is no model
  EXPECT_EQ(commandOf(68).command, Command::kRelativeDepth);  // D
  EXPECT_EQ(commandOf(84).command, Command::kContours);       // T
  EXPECT_EQ(commandOf(71).command, Command::kAmbientOcclusion);  // G
  EXPECT_EQ(commandOf(90).command, Command::kNone);  // Z
  EXPECT_EQ(commandOf(-1).command, Command::kNone);
  const Command offered[] = {Command::kLead, Command::kSnap, Command::kBack};
  EXPECT_EQ(tessera::interact::keysHelp(offered), "L lead, N snap, Backspace back");
}

// A shading key switches its filter on or off and keeps the others as they are.
TEST(Keys, ShadingKeysSwitchOneFilterAndKeepTheOthers) {
  using tessera::interact::shadingEdit;
  tessera::scene::Settings s;
  s.mutable_analysis()->set_relative_depth_radius(40);
  auto e = shadingEdit(Command::kAmbientOcclusion, s, 0.5);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->delta.analysis().ao_strength(), 1.0f);
  EXPECT_EQ(e->delta.analysis().relative_depth_radius(), 40u);
  EXPECT_FALSE(e->delta.has_shading());
  EXPECT_EQ(e->said, "ambient occlusion on");
  *s.mutable_analysis() = e->delta.analysis();
  e = shadingEdit(Command::kAmbientOcclusion, s, 0.5);
  EXPECT_EQ(e->delta.analysis().ao_strength(), 0.0f);
  e = shadingEdit(Command::kContours, s, 0.5);
  EXPECT_EQ(e->delta.analysis().contour_interval(), 0.5);
  EXPECT_EQ(e->said, "contour lines every 0.5 m");
  e = shadingEdit(Command::kShading, s, 0.5);
  EXPECT_EQ(e->delta.shading(), tessera::scene::SHADING_EDL);
  EXPECT_FALSE(e->delta.has_analysis());
  EXPECT_FALSE(shadingEdit(Command::kLead, s, 0.5));
  EXPECT_EQ(tessera::interact::roundContourInterval(3.0), 0.1);
  EXPECT_EQ(tessera::interact::roundContourInterval(100.0), 2.0);
  EXPECT_EQ(tessera::interact::roundContourInterval(std::nan("")), 1.0);
}

TEST(Keys, MeasureStepsThroughItsModesAndOff) {
  ToolKeys k;
  EXPECT_EQ(k.tool(), Tool::kNone);
  EXPECT_EQ(k.press(Command::kMeasure), "measuring: distance (click points)");
  EXPECT_EQ(k.measureMode(), Mode::kDistance);
  EXPECT_NE(k.press(Command::kMeasure).find("measuring: path (click points, Enter ends"),
            std::string::npos);
  k.press(Command::kMeasure);
  EXPECT_EQ(k.measureMode(), Mode::kAngle);
  k.press(Command::kMeasure);
  EXPECT_EQ(k.measureMode(), Mode::kArea);
  EXPECT_EQ(MeasureTool::typeOf(k.measureMode()), tessera::scene::MeasurementPayload::AREA);
  EXPECT_EQ(k.press(Command::kMeasure), "measuring off");
  EXPECT_EQ(k.tool(), Tool::kNone);
  EXPECT_EQ(k.measureMode(), Mode::kOff);
}

TEST(Keys, OneToolAtATime) {
  ToolKeys k;
  k.press(Command::kMeasure);
  k.press(Command::kMeasure);  // path
  EXPECT_EQ(k.press(Command::kLasso).rfind("lasso on", 0), 0u);
  EXPECT_EQ(k.tool(), Tool::kLasso);
  EXPECT_EQ(k.measureMode(), Mode::kOff);  // the lasso turned measuring off
  EXPECT_EQ(k.press(Command::kAddNote), "add note: click on the model where it goes");
  EXPECT_EQ(k.tool(), Tool::kNote);
  EXPECT_EQ(k.press(Command::kMeasure), "measuring: distance (click points)");  // from the start
  EXPECT_EQ(k.press(Command::kSnap).rfind("snap on", 0), 0u);
  EXPECT_EQ(k.press(Command::kSnap), "snap off");
  EXPECT_EQ(k.tool(), Tool::kNone);
  EXPECT_EQ(k.press(Command::kAddNote), "add note: click on the model where it goes");
  EXPECT_EQ(k.press(Command::kAddNote), "add note: cancelled");
  // Commands that are no tool's change nothing.
  k.press(Command::kLasso);
  EXPECT_EQ(k.press(Command::kEnd), "");
  EXPECT_EQ(k.press(Command::kLead), "");
  EXPECT_EQ(k.tool(), Tool::kLasso);
  // A panel chooses directly; measuring "off" is no tool.
  k.choose(Tool::kMeasure, Mode::kAngle);
  EXPECT_EQ(k.measureMode(), Mode::kAngle);
  k.choose(Tool::kMeasure, Mode::kOff);
  EXPECT_EQ(k.tool(), Tool::kNone);
}

}  // namespace
