#include <tessera/core/check.h>

namespace tessera {

void failCheck(const char* condition, const char* file, int line, const std::string& what) {
  throw PreconditionError(what + " (precondition `" + condition + "` failed at " + file + ":" +
                          std::to_string(line) + ")");
}

}  // namespace tessera
