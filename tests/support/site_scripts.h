// What the remote-site tests (tests/collab/) share: reading small files (temp_dir.h writes them),
// cameras as scene/script JSON, and the public key tessera-site keygen prints.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

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

/// tessera-master's argv with the wall over ZeroMQ on an ephemeral loopback port, `wall` and
/// `scene`; the caller appends the rest.
inline std::vector<std::string> zmqMaster(const std::string& master,
                                          const std::filesystem::path& wall,
                                          const std::filesystem::path& scene) {
  return {master,   "--transport", "zmq",     "--listen",    "tcp://127.0.0.1:*",
          "--wall", wall.string(), "--scene", scene.string()};
}

/// tessera-master holding `camera_json` (a config.proto Camera as JSON) for `seconds` of real time
/// (30 frames a second at most), the wall over ZeroMQ and remote sites over CURVE on ephemeral
/// loopback ports: the argv, after writing its script to `run`/hold.json. `dir` holds
/// wall.json, scene.json, master.key and allow.txt; `extra` is appended.
inline std::vector<std::string> masterWithSites(const std::string& master,
                                                const std::filesystem::path& dir,
                                                const std::filesystem::path& run, double seconds,
                                                const std::string& camera_json,
                                                const std::vector<std::string>& extra) {
  const std::string hold = camera_json.substr(1, camera_json.size() - 2);
  writeText(run / "hold.json", R"({"name": "hold", "keyframes": [{"time": 0, )" + hold +
                                   R"(}, {"time": )" + std::to_string(seconds) + ", " + hold +
                                   "}]}");
  std::vector<std::string> argv = zmqMaster(master, dir / "wall.json", dir / "scene.json");
  argv.insert(argv.end(), {"--script", (run / "hold.json").string(), "--max-fps", "30", "--stats",
                           (run / "stats.csv").string(), "--sites", "tcp://127.0.0.1:*",
                           "--site-key", (dir / "master.key").string(), "--allow",
                           (dir / "allow.txt").string(), "--node-timeout", "5000"});
  argv.insert(argv.end(), extra.begin(), extra.end());
  return argv;
}

/// Sets `option`'s value in an argv that has it (e.g. masterWithSites' "--max-fps").
inline void setOption(std::vector<std::string>& argv, const std::string& option,
                      const std::string& value) {
  for (size_t i = 0; i + 1 < argv.size(); ++i)
    if (argv[i] == option) argv[i + 1] = value;
}

/// A camera path holding `camera_json` for `seconds` with a wall screenshot (shot000.png,
/// shot001.png ...) every `every` seconds from `from` on, written to `path` (masterWithSites'
/// hold.json, replaced).
inline void writeHoldWithScreenshots(const std::filesystem::path& path,
                                     const std::string& camera_json, double seconds, double from,
                                     double every) {
  const std::string hold = camera_json.substr(1, camera_json.size() - 2);
  std::string actions;
  int n = 0;
  for (double t = from; t < seconds - 0.2; t += every, ++n) {
    char a[96];
    std::snprintf(a, sizeof a, R"(%s{"time": %.3f, "screenshot": "shot%03d.png"})", n ? ", " : "",
                  t, n);
    actions += a;
  }
  writeText(path, R"({"name": "hold", "keyframes": [{"time": 0, )" + hold + R"(}, {"time": )" +
                      std::to_string(seconds) + ", " + hold + "}], \"actions\": [" + actions +
                      "]}");
}

/// A headless tessera-site joining `sites` as `name` with `key_file`, playing `script`, writing
/// to `out`; `extra` is appended.
inline std::vector<std::string> headlessSite(const std::string& site, const std::string& sites,
                                             const std::string& master_key, const std::string& name,
                                             const std::filesystem::path& key_file,
                                             const std::filesystem::path& out,
                                             const std::filesystem::path& script,
                                             const std::vector<std::string>& extra) {
  std::vector<std::string> argv = {
      site,     "--master",   sites,      "--master-key",    master_key,
      "--name", name,         "--key",    key_file.string(), "--headless",
      "-o",     out.string(), "--script", script.string()};
  argv.insert(argv.end(), extra.begin(), extra.end());
  return argv;
}

/// The first capture of `pattern` in `log` ("" when none).
inline std::string captured(const std::string& log, const std::string& pattern) {
  std::smatch m;
  return std::regex_search(log, m, std::regex(pattern)) ? m[1].str() : "";
}

/// The public key in what `tessera-site keygen` printed ("" when none).
inline std::string publicKeyOf(const std::string& keygen_output) {
  std::smatch m;
  if (!std::regex_search(keygen_output, m, std::regex("^(\\S{40})$", std::regex::multiline)))
    return "";
  return m[1].str();
}

}  // namespace tessera::test
