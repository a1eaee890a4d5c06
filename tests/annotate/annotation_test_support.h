// What the annotation database's tests share: a text item, a file's bytes, a run of
// tessera-annotate (a real process, its output in a log).
#pragma once

#include <tessera/annotate/annotation_db.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "../support/process.h"

namespace tessera::test {

inline annotate::Item textItem(const std::string& layer, const std::string& title,
                               const std::string& text = "") {
  annotate::Item it;
  it.layer = layer;
  it.title = title;
  it.text = text;
  return it;
}

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

/// Runs tessera-annotate with `args`, output to `log`: its exit code (-1000: no exit in 60 s).
inline int runTool(const std::vector<std::string>& args, const std::filesystem::path& log) {
  std::vector<std::string> argv{TESSERA_ANNOTATE_TOOL};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv, log);
  const auto code = p.wait(60.0);
  return code ? *code : -1000;
}

}  // namespace tessera::test
