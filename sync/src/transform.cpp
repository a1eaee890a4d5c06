#include <tessera/sync/transform.h>

#include <cmath>
#include <cstring>

#include <glm/gtc/type_ptr.hpp>

namespace tessera::sync {

namespace {

glm::dmat4 rigidMatrix(const glm::quat& rotation, const glm::dvec3& translation) {
  // In doubles from the float quaternion, so the master and every replica decode the same bits,
  // divided by its squared length instead of normalised first: a quaternion a float rounding
  // off unit length still gives a rotation, and quarter turns (w = z = 0.70710677f) give exact
  // zeros and ones, so encodeTransform() finds them rigid.
  const double w = rotation.w, x = rotation.x, y = rotation.y, z = rotation.z;
  const double n = w * w + x * x + y * y + z * z;
  glm::dmat4 m(1.0);
  m[0][0] = 1.0 - 2.0 * (y * y + z * z) / n;
  m[0][1] = 2.0 * (x * y + w * z) / n;
  m[0][2] = 2.0 * (x * z - w * y) / n;
  m[1][0] = 2.0 * (x * y - w * z) / n;
  m[1][1] = 1.0 - 2.0 * (x * x + z * z) / n;
  m[1][2] = 2.0 * (y * z + w * x) / n;
  m[2][0] = 2.0 * (x * z + w * y) / n;
  m[2][1] = 2.0 * (y * z - w * x) / n;
  m[2][2] = 1.0 - 2.0 * (x * x + y * y) / n;
  m[3] = glm::dvec4(translation, 1.0);
  return m;
}

}  // namespace

scene::Transform rigidTransform(const glm::quat& rotation, const glm::dvec3& translation) {
  scene::Transform t;
  for (double v : {translation.x, translation.y, translation.z}) t.add_translation(v);
  for (float v : {rotation.w, rotation.x, rotation.y, rotation.z}) t.add_rotation(v);
  return t;
}

glm::dmat4 transformMatrix(const scene::Transform& t) {
  if (t.m_size() == 16) return glm::make_mat4(t.m().data());
  if (t.translation_size() == 3 && t.rotation_size() == 4)
    return rigidMatrix(glm::quat(t.rotation(0), t.rotation(1), t.rotation(2), t.rotation(3)),
                       glm::dvec3(t.translation(0), t.translation(1), t.translation(2)));
  return glm::dmat4(1.0);
}

scene::Transform encodeTransform(std::span<const double> matrix) {
  scene::Transform t;
  if (matrix.size() != 16) return t;
  const glm::dmat4 m = glm::make_mat4(matrix.data());
  // Only an affine map can be rigid; quat_cast of anything else gives some quaternion whose
  // matrix differs, which the exact comparison below rejects.
  if (m[0][3] == 0.0 && m[1][3] == 0.0 && m[2][3] == 0.0 && m[3][3] == 1.0) {
    const glm::dquat q = glm::quat_cast(glm::dmat3(m));
    const glm::quat qf(float(q.w), float(q.x), float(q.y), float(q.z));
    const glm::dvec3 translation(m[3]);
    const glm::dmat4 back = rigidMatrix(qf, translation);
    if (std::isfinite(glm::length(q)) && std::memcmp(&back, &m, sizeof m) == 0)
      return rigidTransform(qf, translation);
  }
  t.mutable_m()->Assign(matrix.begin(), matrix.end());
  return t;
}

}  // namespace tessera::sync
