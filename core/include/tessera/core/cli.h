// The command-line layer every tool shares (CLI11): one parse wrapper that maps every parse error
// to the documented exit code, validators for numbers (finite, in range, no integer wrap),
// checked parsers for composite values (WxH, X,Y,Z, a view), the refusal to write over an input,
// and the top-level handler that turns any escaping exception into a message and an exit code.
//
// Why not CLI::Range / CLI::PositiveNumber: every comparison with NaN is false, so they let NaN
// through; and CLI11 2.1 converts "-1" or "18446744073709551617" into a uint64_t option as
// 2^64 - 1 without a word. The validators here read the text themselves.
#pragma once

#include <CLI/CLI.hpp>

#include <cctype>
#include <charconv>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>

#include <glm/vec3.hpp>

namespace tessera::cli {

/// Exit codes every tool shares (README, "Exit codes"). Tools add their own above 3.
constexpr int kExitOk = 0;
constexpr int kExitBadInput = 1;        ///< bad input data, or a failure reported by message
constexpr int kExitBadCommandLine = 2;  ///< a parse error, a bad value, an output that is an input
constexpr int kExitWriteFailed = 3;     ///< an output could not be written (disk full...)

/// A command-line value that parsed but cannot be used (thrown by the checks below, and by the
/// tools' own checks after parsing); runMain() exits kExitBadCommandLine with its message.
/// The message starts with the option ("--size 0x480: ...").
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Parses the command line. Returns std::nullopt to go on; otherwise the exit code main() must
/// return: 0 after --help (printed to stdout), kExitBadCommandLine after any parse or
/// validation error (printed to stderr as "TOOL: MESSAGE", the message naming the option).
std::optional<int> parse(CLI::App& app, int argc, char** argv, const std::string& tool);

/// What parse() does with a ParseError caught elsewhere (the cluster tools parse after MPI_Init
/// and must answer waiting ranks first): prints it and returns the exit code, 0 for --help.
int exitCode(CLI::App& app, const CLI::ParseError& e, const std::string& tool);

/// Runs a tool's body. Anything that escapes is caught here and reported as "TOOL: WHAT":
/// UsageError and CLI::ParseError exit kExitBadCommandLine, std::bad_alloc ("out of memory")
/// and any other exception `failure_code`. Stack unwinding removes the temporary files the
/// body owns (RAII), which an exception escaping main() would not guarantee.
int runMain(const std::string& tool, const std::function<int()>& body,
            int failure_code = kExitBadInput);

/// A second SIGINT or SIGTERM this long after the first terminates at once; sooner, it is the
/// same request (a supervisor signalling the process and its group).
inline constexpr std::chrono::milliseconds kSecondSignalAfter{1000};

/// Makes SIGINT and SIGTERM requests to stop: the first sets stopSignal() and the long-running
/// loops (the master's frames, a site's) end at their next frame as if their script had ended,
/// with their normal exit code; a second one kSecondSignalAfter or more later terminates at
/// once (the default action is restored). Call it
/// first in main(), before any thread starts: the signals are blocked in every thread and taken
/// by one of their own, so no blocking call is interrupted (EINTR).
void catchStopSignals();

/// The signal that asked to stop (SIGINT, SIGTERM), or 0. Async-signal-safe to set, cheap to read.
int stopSignal();

/// A finite number in [lo, hi]; the message names the range ("--node-timeout: 'nan' is not a
/// finite number in [0, 3600000]").
CLI::Validator finiteRange(double lo, double hi);

/// A finite number in (0, hi].
CLI::Validator positiveFinite(double hi);

/// Parses `text` as a decimal integer of type T: digits only (a leading '-' for signed T), no
/// octal or hex, no wrap. Returns the reason it is not in [lo, hi], or nullopt with `out` set.
template <typename T>
std::optional<std::string> parseInteger(const std::string& text, T lo, T hi, T& out) {
  static_assert(std::is_integral_v<T>);
  const char* first = text.data();
  const char* last = text.data() + text.size();
  const auto range = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  const auto [end, ec] = std::from_chars(first, last, out);
  const bool digits =
      !text.empty() &&
      (std::isdigit(static_cast<unsigned char>(text[0])) ||
       (text[0] == '-' && text.size() > 1 && std::isdigit(static_cast<unsigned char>(text[1]))));
  if (ec == std::errc::result_out_of_range && digits)
    return text[0] == '-' ? "at least " + std::to_string(lo) + " (got " + text + ")"
                          : "at most " + std::to_string(hi) + " (got " + text + ")";
  if (ec != std::errc() || end != last || !digits)
    return "'" + text + "' is not an integer in " + range;
  if (out < lo) return "at least " + std::to_string(lo) + " (got " + text + ")";
  if (out > hi) return "at most " + std::to_string(hi) + " (got " + text + ")";
  return std::nullopt;
}

/// An integer of the option's type T in [lo, hi] ("--threads: at most 256 (got 100000)").
template <typename T>
CLI::Validator integerRange(T lo, T hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        T value{};
        return parseInteger<T>(text, lo, hi, value).value_or(std::string());
      },
      "INT in [" + std::to_string(lo) + " - " + std::to_string(hi) + "]");
}

/// Any integer of type T, but never wrapped ("-1" into an unsigned option is refused).
template <typename T>
CLI::Validator anyInteger() {
  return integerRange<T>(std::numeric_limits<T>::min(), std::numeric_limits<T>::max());
}

struct Size {
  uint32_t width = 0, height = 0;
};

/// "WxH", each in [1, max]; throws UsageError naming `option`.
Size parseSize(const std::string& text, const std::string& option, uint32_t max);

/// "X,Y,Z" of finite numbers; throws UsageError naming `option`.
glm::dvec3 parseVec3(const std::string& text, const std::string& option);

/// As parseVec3, each component in [lo, hi] (a colour: 0, 1).
glm::dvec3 parseVec3(const std::string& text, const std::string& option, double lo, double hi);

/// Throws UsageError when `output` is, by any path (symlinks, "./", hard links: the same
/// device and inode), one of `inputs`: "OPTION OUTPUT: is the input INPUT; refusing to write
/// over an input". Inputs that do not exist are ignored; call before anything is written.
void refuseOverwrite(const std::filesystem::path& output,
                     std::span<const std::filesystem::path> inputs, const std::string& option);

/// Throws UsageError when a file cannot be written at `output` (notWritable()), naming `option`:
/// an output written at the end of a run is refused at its start.
void refuseUnwritable(const std::filesystem::path& output, const std::string& option);

}  // namespace tessera::cli
