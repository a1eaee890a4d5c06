// config::Vec3, the schema's 3-vector (metres), to and from glm, and its finiteness: the one
// conversion every module uses.
#pragma once

#include <cmath>

#include <glm/glm.hpp>

#include <tessera/config.pb.h>

namespace tessera::sync {

inline glm::dvec3 vec(const config::Vec3& v) {
  return {v.x(), v.y(), v.z()};
}

inline void set(config::Vec3* d, const glm::dvec3& v) {
  d->set_x(v.x);
  d->set_y(v.y);
  d->set_z(v.z);
}

inline config::Vec3 toVec3(const glm::dvec3& v) {
  config::Vec3 out;
  set(&out, v);
  return out;
}

inline bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

inline bool finite(const config::Vec3& v) {
  return finite(vec(v));
}

}  // namespace tessera::sync
