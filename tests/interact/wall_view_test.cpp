// The console's View panel without a window (interact/wall_view.h): what its head and inset
// controls read from the scene and the edits they make. A moved or switched-off inset goes into
// the scene as a camera path's setInset puts it there and reaches a replica with the next frame;
// the weights every node applies follow it; edits off the wall or behind a tile are refused by
// field and change nothing.
#include <gtest/gtest.h>

#include <cmath>

#include <tessera/interact/wall_view.h>
#include <tessera/render/inset.h>
#include <tessera/sync/config.h>
#include <tessera/sync/vec3.h>

namespace {

using namespace tessera;

/// Two 0.96 x 0.54 m tiles of 96 x 54 pixels and a 0.3 x 0.2 m inset over their bezel.
config::WallConfig wall() {
  return sync::parseWallConfig(R"({"tiles": [
      {"name": "a", "x": 0, "y": 0, "width": 0.96, "height": 0.54, "pixelWidth": 96,
       "pixelHeight": 54},
      {"name": "b", "x": 0.98, "y": 0, "width": 0.96, "height": 0.54, "pixelWidth": 96,
       "pixelHeight": 54}],
      "insets": [{"name": "fovea", "x": 0.82, "y": 0.17, "width": 0.3, "height": 0.2,
                  "pixelWidth": 60, "pixelHeight": 40, "blendBand": 0.02}],
      "eye": {"x": 0.97, "y": 0.27, "z": 1.5}})",
                               "wall.json", "");
}

/// A white picture of a slot's pixel size, weighed as its node weighs it; the count of pixels
/// left white.
size_t whiteAfterWeights(const config::WallConfig& w, const render::WallSlot& slot,
                         const scene::Settings& settings) {
  render::Image img;
  img.width = slot.tile.pixel_width();
  img.height = slot.tile.pixel_height();
  img.rgba.assign(size_t(img.width) * img.height * 4, 255);
  render::applySlotWeights(w, slot, settings.inset(), img);
  size_t white = 0;
  for (size_t i = 0; i < img.rgba.size(); i += 4) white += img.rgba[i] == 255;
  return white;
}

TEST(WallView, TheInsetControlMovesAndSwitchesTheInsetThroughTheScene) {
  const config::WallConfig w = wall();
  sync::SceneGraph g, replica, scripted;
  g.takeFrame(1, 0);
  replica.apply(g.snapshot());
  scene::InsetCentre c = interact::currentInset(w, g.settings(), 0);
  EXPECT_EQ(c.name(), "fovea");
  EXPECT_NEAR(c.x(), 0.97, 1e-12);
  EXPECT_NEAR(c.y(), 0.27, 1e-12);
  EXPECT_FALSE(c.hidden());
  const std::vector<render::WallSlot> slots = render::wallSlots(w);
  const size_t under = whiteAfterWeights(w, slots[0], g.settings());
  EXPECT_LT(under, 96u * 54u) << "the context is black under the inset";

  // Moved right onto tile b: the slider's edit, and the script's setInset of the same centre.
  c.set_x(1.5);
  EXPECT_FALSE(interact::applyInset(g, w, c));
  replica.apply(g.takeFrame(2, 0));
  scripted.setInset(c);
  EXPECT_EQ(interact::currentInset(w, replica.settings(), 0).x(), 1.5);
  EXPECT_EQ(replica.settings().inset().SerializeAsString(),
            scripted.settings().inset().SerializeAsString());
  EXPECT_EQ(whiteAfterWeights(w, slots[0], replica.settings()), 96u * 54u)
      << "tile a is whole once the inset left it";
  EXPECT_LT(whiteAfterWeights(w, slots[1], replica.settings()), 96u * 54u);

  // Switched off: the context is whole under it and the inset's own node draws black.
  c.set_hidden(true);
  EXPECT_FALSE(interact::applyInset(g, w, c));
  replica.apply(g.takeFrame(3, 0));
  EXPECT_TRUE(interact::currentInset(w, replica.settings(), 0).hidden());
  EXPECT_EQ(whiteAfterWeights(w, slots[1], replica.settings()), 96u * 54u);
  EXPECT_EQ(whiteAfterWeights(w, slots[2], replica.settings()), 0u);
  // On again where it was.
  c.set_hidden(false);
  EXPECT_FALSE(interact::applyInset(g, w, c));
  replica.apply(g.takeFrame(4, 0));
  EXPECT_FALSE(interact::currentInset(w, replica.settings(), 0).hidden());
  EXPECT_LT(whiteAfterWeights(w, slots[1], replica.settings()), 96u * 54u);

  // Off the wall, or an inset the wall lacks: refused by name, nothing changes.
  scene::InsetCentre off = c;
  off.set_x(1.9);
  const auto why = interact::applyInset(g, w, off);
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("inset.fovea: inset 'fovea' centred at (1.9, 0.27)"), std::string::npos)
      << *why;
  off = c;
  off.set_name("other");
  EXPECT_NE(interact::applyInset(g, w, off).value_or("").find("the wall has no inset 'other'"),
            std::string::npos);
  off = c;
  off.set_y(std::nan(""));
  EXPECT_TRUE(interact::applyInset(g, w, off));
  EXPECT_FALSE(g.hasPendingChanges());
}

TEST(WallView, TheHeadControlsMoveAndTurnTheHeadInFrontOfTheWall) {
  const config::WallConfig w = wall();
  sync::SceneGraph g, replica;
  g.takeFrame(1, 0);
  replica.apply(g.snapshot());
  scene::Head h = interact::currentHead(w, g.settings());
  EXPECT_EQ(sync::vec(h.eye()), sync::vec(w.eye()));
  EXPECT_EQ(sync::vec(h.right()), glm::dvec3(1, 0, 0));
  EXPECT_EQ(h.eye_separation(), sync::kDefaultEyeSeparation);
  EXPECT_NEAR(interact::headYawDegrees(h), 0.0, 1e-12);
  interact::setHeadYaw(h, 30.0);
  EXPECT_NEAR(interact::headYawDegrees(h), 30.0, 1e-12);
  EXPECT_NEAR(h.right().z(), 0.5, 1e-12);  // turned right: the right axis towards the wall's +z
  h.mutable_eye()->set_x(0.5);
  EXPECT_FALSE(interact::applyHead(g, w, h));
  replica.apply(g.takeFrame(2, 0));
  const sync::ViewerHead seen = sync::viewerHead(w, replica.settings());
  EXPECT_EQ(seen.eye, glm::dvec3(0.5, 0.27, 1.5));
  EXPECT_NEAR(seen.right.z, 0.5, 1e-12);
  // A stereo eye: the head's point moved by half its separation along its turned right axis.
  const glm::dvec3 right_eye = sync::eyeOffset(w, seen, 1, 0.1) + sync::vec(w.eye());
  EXPECT_NEAR(glm::length(right_eye - seen.eye), 0.0325, 1e-12);
  EXPECT_NEAR(right_eye.z, 1.5 + 0.0325 * 0.5, 1e-12);

  scene::Head behind = h;
  behind.mutable_eye()->set_z(-0.2);
  const auto why = interact::applyHead(g, w, behind);
  ASSERT_TRUE(why);
  EXPECT_EQ(why->rfind("head.eye: the head (0.5, 0.27, -0.2) is behind the plane of tiles[0] "
                       "('a')",
                       0),
            0u)
      << *why;
  scene::Head zero = h;
  sync::set(zero.mutable_right(), glm::dvec3(0.0));
  EXPECT_EQ(interact::applyHead(g, w, zero).value_or("").rfind("head.right:", 0), 0u);
  EXPECT_FALSE(g.hasPendingChanges());
}

}  // namespace
