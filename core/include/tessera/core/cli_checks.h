// Command-line checks the tools share (CLI11). CLI::Range lets NaN through (every comparison
// with NaN is false), so a number option that must be a real value uses finiteRange().
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <string>

namespace tessera {

/// A finite number in [lo, hi]; the message names the range ("--node-timeout: 'nan' is not a
/// finite number in [0, 3600000]").
inline CLI::Validator finiteRange(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0' || !std::isfinite(v) || v < lo || v > hi)
          return "'" + text + "' is not a finite number in [" + CLI::detail::to_string(lo) + ", " +
                 CLI::detail::to_string(hi) + "]";
        return {};
      },
      "FINITE in [" + CLI::detail::to_string(lo) + " - " + CLI::detail::to_string(hi) + "]");
}

}  // namespace tessera
