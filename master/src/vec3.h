// Private: config::Vec3 (the schema's 3-vector, metres) to and from glm, for the master's
// camera code (navigation, the console's notes).
#pragma once

#include <glm/glm.hpp>

#include <tessera/config.pb.h>

namespace tessera::master::detail {

inline glm::dvec3 vec(const config::Vec3& v) {
  return {v.x(), v.y(), v.z()};
}

inline void set(config::Vec3* d, const glm::dvec3& v) {
  d->set_x(v.x);
  d->set_y(v.y);
  d->set_z(v.z);
}

}  // namespace tessera::master::detail
