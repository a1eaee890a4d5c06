// What the remote-site tests (tests/collab/) share: reading small files (temp_dir.h writes them),
// cameras as scene/script JSON, and the public key tessera-site keygen prints.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include <glm/glm.hpp>

#include "temp_dir.h"  // writeText()

namespace tessera::test {

inline std::string readText(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A camera as config.proto Camera JSON, up +y.
inline std::string cameraJson(glm::dvec3 eye, glm::dvec3 target) {
  char s[256];
  std::snprintf(
      s, sizeof s,
      R"({"eye": {"x": %.17g, "y": %.17g, "z": %.17g}, "target": {"x": %.17g, "y": %.17g, "z": %.17g}, "up": {"y": 1}})",
      eye.x, eye.y, eye.z, target.x, target.y, target.z);
  return s;
}

/// The public key in what `tessera-site keygen` printed ("" when none).
inline std::string publicKeyOf(const std::string& keygen_output) {
  std::smatch m;
  if (!std::regex_search(keygen_output, m, std::regex("^(\\S{40})$", std::regex::multiline)))
    return "";
  return m[1].str();
}

}  // namespace tessera::test
