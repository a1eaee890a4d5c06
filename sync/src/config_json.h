// Private helpers shared by the JSON config loaders (walls, scenes, camera paths): errors in the
// form "sync::loadX(): FILE: FIELD: what", reading a file, strict JSON parsing.
#pragma once

#include <google/protobuf/util/json_util.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <glm/glm.hpp>

#include <tessera/core/file_checks.h>
#include <tessera/sync/config.h>

#include <tessera/sync/vec3.h>
#include <tessera/sync/view.h>

namespace tessera::sync::detail {

[[noreturn]] inline void failConfig(const char* fn, const std::string& file,
                                    const std::string& field, const std::string& what) {
  throw ConfigError(std::string(fn) + ": " + file + ": " + (field.empty() ? "" : field + ": ") +
                    what);
}

inline std::string readConfigFile(const std::filesystem::path& path, const char* fn) {
  // A FIFO or device would block the reader or never end.
  if (const auto why = notRegularFile(path))
    failConfig(fn, path.string(), "", "cannot open: " + *why);
  std::ifstream in(path, std::ios::binary);
  if (!in) failConfig(fn, path.string(), "", "cannot open");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Parses `json` into `msg`; an unknown (misspelt) field is an error, not silently ignored.
template <typename Message>
void parseConfigJson(const std::string& json, const std::string& name, const char* fn,
                     Message& msg) {
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = false;
  auto status = google::protobuf::util::JsonStringToMessage(json, &msg, options);
  if (!status.ok())
    failConfig(fn, name, "",
               "not a valid " + msg.GetDescriptor()->name() + ": " + std::string(status.message()));
}

/// A camera from a file, by the one view rule (view.h). Errors name `field` (or `field`.up).
inline void checkConfigCamera(const config::Camera& c, const char* fn, const std::string& file,
                              const std::string& field) {
  if (const auto problem = viewProblem(c))
    failConfig(fn, file, problem->on_up ? field + ".up" : field, problem->what);
}

}  // namespace tessera::sync::detail
