// Always-on preconditions for API misuse (stay in release builds), after Filament's
// FILAMENT_CHECK_PRECONDITION. Internal invariants use plain assert().
#pragma once

#include <stdexcept>
#include <string>

namespace tessera {

/// Thrown by TESSERA_CHECK: a caller broke a documented precondition.
class PreconditionError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

[[noreturn]] void failCheck(const char* condition, const char* file, int line,
                            const std::string& what);

}  // namespace tessera

#define TESSERA_CHECK(cond, what)                                         \
  do {                                                                    \
    if (!(cond)) ::tessera::failCheck(#cond, __FILE__, __LINE__, (what)); \
  } while (0)
