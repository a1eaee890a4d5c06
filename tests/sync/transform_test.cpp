// sync/transform.h: a node transform as 16 numbers or in the rigid form, and back.

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <tessera/core/check.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/transform.h>
#include <tessera/sync/wire.h>

namespace tessera::sync {
namespace {

bool sameBits(const glm::dmat4& a, const glm::dmat4& b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

std::vector<double> numbers(const glm::dmat4& m) {
  return {glm::value_ptr(m), glm::value_ptr(m) + 16};
}

TEST(Transform, RigidFormDecodesToTheRotationAndTranslation) {
  std::mt19937 rng(7);
  std::normal_distribution<float> normal;
  for (int i = 0; i < 1000; ++i) {
    const glm::quat q = glm::normalize(glm::quat(normal(rng), normal(rng), normal(rng), normal(rng)));
    const glm::dvec3 t(636590.0 + normal(rng), 847900.0 + normal(rng), normal(rng));
    const glm::dmat4 m = transformMatrix(rigidTransform(q, t));
    // Against glm's own quaternion to matrix, in doubles.
    const glm::dmat3 reference = glm::mat3_cast(glm::normalize(glm::dquat(q)));
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) ASSERT_NEAR(m[c][r], reference[c][r], 1e-12);
    // A rotation: orthonormal, determinant 1, the last row 0 0 0 1; the translation exact.
    const glm::dmat3 r(m);
    const glm::dmat3 should_be_identity = glm::transpose(r) * r;
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) ASSERT_NEAR(should_be_identity[c][k], c == k ? 1.0 : 0.0, 1e-14);
    ASSERT_NEAR(glm::determinant(r), 1.0, 1e-14);
    ASSERT_EQ(m[0][3], 0.0);
    ASSERT_EQ(m[1][3], 0.0);
    ASSERT_EQ(m[2][3], 0.0);
    ASSERT_EQ(m[3][3], 1.0);
    ASSERT_EQ(glm::dvec3(m[3]), t);
  }
  // q and -q are the same rotation; a quaternion off unit length by float rounding decodes as
  // the unit one.
  const glm::quat q(0.5f, 0.5f, -0.5f, 0.5f);
  EXPECT_TRUE(sameBits(transformMatrix(rigidTransform(q, {})),
                       transformMatrix(rigidTransform(-q, {}))));
  EXPECT_TRUE(sameBits(transformMatrix(scene::Transform()), glm::dmat4(1.0)));
}

TEST(Transform, EncodingGivesBackExactlyTheNumbersItWasGiven) {
  std::mt19937 rng(11);
  std::normal_distribution<double> normal;
  int rigid = 0;
  for (int i = 0; i < 2000; ++i) {
    glm::dmat4 m(1.0);
    switch (i % 4) {
      case 0:  // a translation, as a georeferenced place or sketch has
        m[3] = glm::dvec4(636590.0 + normal(rng), 847900.25 * normal(rng), normal(rng), 1.0);
        break;
      case 1: {  // quarter and half turns, and a translation
        const glm::dmat3 turns[4] = {glm::dmat3(1.0), glm::dmat3(0, 1, 0, -1, 0, 0, 0, 0, 1),
                                     glm::dmat3(1, 0, 0, 0, 0, 1, 0, -1, 0),
                                     glm::dmat3(-1, 0, 0, 0, 1, 0, 0, 0, -1)};
        m = glm::dmat4(turns[(i / 4) % 4]);
        m[3] = glm::dvec4(normal(rng), normal(rng), 2.0, 1.0);
        break;
      }
      case 2:  // a general rotation in doubles (seldom exact in floats: then 16 numbers)
        m = glm::mat4_cast(glm::normalize(glm::dquat(normal(rng), normal(rng), normal(rng),
                                                     normal(rng))));
        m[3] = glm::dvec4(normal(rng), normal(rng), normal(rng), 1.0);
        break;
      default:  // scaled, sheared
        for (int c = 0; c < 3; ++c)
          for (int r = 0; r < 3; ++r) m[c][r] = normal(rng) + (c == r ? 3.0 : 0.0);
        break;
    }
    const std::vector<double> in = numbers(m);
    const scene::Transform t = encodeTransform(in);
    ASSERT_TRUE(sameBits(transformMatrix(t), m)) << "case " << i % 4;
    if (t.m_size() == 0) {
      ++rigid;
      EXPECT_NE(i % 4, 3) << "a scaled or sheared matrix is not rigid";
    }
    if (i % 4 <= 1) {
      EXPECT_EQ(t.m_size(), 0) << "translations and quarter turns are rigid";
    }
  }
  EXPECT_GE(rigid, 1000);
  EXPECT_EQ(encodeTransform({}).ByteSizeLong(), 0u) << "none: identity";
}

TEST(Transform, ThePoseFormIsAThirdOfTheBytes) {
  const scene::Transform pose =
      rigidTransform(glm::normalize(glm::quat(0.3f, -0.5f, 0.7f, 0.1f)), {636590.5, 847900.25, 3.0});
  const glm::dmat4 m = transformMatrix(pose);
  scene::Transform full;
  for (double v : numbers(m)) full.add_m(v);
  EXPECT_LE(pose.ByteSizeLong(), 44u);
  EXPECT_GE(full.ByteSizeLong(), 130u);
}

TEST(Transform, ReplicasDecodeThePoseToTheMastersBits) {
  SceneGraph master, replica;
  const auto id = master.add(scene::SceneNode::AVATAR, SceneGraph::kRoot, "Kyoto lab");
  const scene::Transform pose =
      rigidTransform(glm::normalize(glm::quat(0.9f, 0.1f, -0.3f, 0.2f)), {1.0 / 3.0, 2.0, -7.0});
  master.setTransform(id, pose);
  replica.apply(parseFrame(serializeFrame(master.takeFrame(1, 0))));
  EXPECT_TRUE(sameBits(transformMatrix(replica.node(id).transform()),
                       transformMatrix(master.node(id).transform())));
  EXPECT_EQ(replica.node(id).transform().m_size(), 0);
  // Back to 16 numbers (a scale): the form changes whole, not field by field.
  glm::dmat4 scaled = transformMatrix(pose) * glm::dmat4(2.0);
  scaled[3][3] = 1.0;
  master.setTransform(id, numbers(scaled));
  replica.apply(parseFrame(serializeFrame(master.takeFrame(2, 0))));
  EXPECT_EQ(replica.node(id).transform().translation_size(), 0);
  EXPECT_TRUE(sameBits(transformMatrix(replica.node(id).transform()), scaled));
  EXPECT_TRUE(replica == master);
  // The master refuses a bad pose as it refuses bad numbers.
  scene::Transform bad = pose;
  bad.set_rotation(0, 5.0f);
  EXPECT_THROW(master.setTransform(id, bad), PreconditionError);
}

}  // namespace
}  // namespace tessera::sync
