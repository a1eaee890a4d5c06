#include <tessera/core/cli.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <thread>

#include <pthread.h>

#include <glm/geometric.hpp>

#include <tessera/core/file_checks.h>

namespace tessera::cli {

namespace {

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

/// strtod over the whole text; nullopt unless it is all one finite number.
std::optional<double> finiteNumber(const std::string& text) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text[0]))) return std::nullopt;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0' || !std::isfinite(v)) return std::nullopt;
  return v;
}

}  // namespace

int exitCode(CLI::App& app, const CLI::ParseError& e, const std::string& tool) {
  if (e.get_exit_code() == int(CLI::ExitCodes::Success)) return app.exit(e);  // --help
  std::fprintf(stderr, "%s: %s\n(--help lists the options)\n", tool.c_str(), e.what());
  return kExitBadCommandLine;
}

std::optional<int> parse(CLI::App& app, int argc, char** argv, const std::string& tool) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return exitCode(app, e, tool);
  }
  return std::nullopt;
}

namespace {

std::atomic<int> gStopSignal{0};

}  // namespace

void catchStopSignals() {
  // Blocked in every thread (they inherit the mask) and taken by sigwait() in one of their own:
  // no handler interrupts a blocking call (ZeroMQ would throw EINTR out of a poll).
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  if (pthread_sigmask(SIG_BLOCK, &set, nullptr) != 0) return;  // signals keep their default
  std::thread([set] {
    int sig = 0;
    if (sigwait(&set, &sig) != 0) return;
    gStopSignal.store(sig);
    const auto first = std::chrono::steady_clock::now();
    // The same request may come twice at once: `timeout` and other supervisors signal the
    // process and then its group, and a terminal's Ctrl-C reaches every process of its group.
    // Only a signal kSecondSignalAfter later is a second request.
    do {
      if (sigwait(&set, &sig) != 0) return;
    } while (std::chrono::steady_clock::now() - first < kSecondSignalAfter);
    // The second one is not ignored: its default action, now.
    std::signal(sig, SIG_DFL);
    pthread_sigmask(SIG_UNBLOCK, &set, nullptr);
    raise(sig);
  }).detach();
}

int stopSignal() {
  return gStopSignal.load(std::memory_order_relaxed);
}

int runMain(const std::string& tool, const std::function<int()>& body, int failure_code) {
  try {
    return body();
  } catch (const UsageError& e) {
    std::fprintf(stderr, "%s: %s\n", tool.c_str(), e.what());
    return kExitBadCommandLine;
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "%s: %s\n", tool.c_str(), e.what());
    return kExitBadCommandLine;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "%s: out of memory (an input or option asks for more than there is)\n",
                 tool.c_str());
    return failure_code;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", tool.c_str(), e.what());
    return failure_code;
  } catch (...) {
    std::fprintf(stderr, "%s: failed with an unknown exception\n", tool.c_str());
    return failure_code;
  }
}

CLI::Validator finiteRange(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        const auto v = finiteNumber(text);
        if (!v || *v < lo || *v > hi)
          return "'" + text + "' is not a finite number in [" + number(lo) + ", " + number(hi) +
                 "]";
        return {};
      },
      "FINITE in [" + number(lo) + " - " + number(hi) + "]");
}

CLI::Validator positiveFinite(double hi) {
  return CLI::Validator(
      [hi](std::string& text) -> std::string {
        const auto v = finiteNumber(text);
        if (!v || !(*v > 0) || *v > hi)
          return "'" + text + "' is not a finite number in (0, " + number(hi) + "]";
        return {};
      },
      "FINITE in (0 - " + number(hi) + "]");
}

Size parseSize(const std::string& text, const std::string& option, uint32_t max) {
  const auto x = text.find('x');
  Size s;
  if (x == std::string::npos ||
      parseInteger<uint32_t>(text.substr(0, x), 1, max, s.width).has_value() ||
      parseInteger<uint32_t>(text.substr(x + 1), 1, max, s.height).has_value()) {
    throw UsageError(option + " " + text + ": expected WxH, each from 1 to " + std::to_string(max) +
                     ", e.g. 1280x720");
  }
  return s;
}

glm::dvec3 parseVec3(const std::string& text, const std::string& option) {
  glm::dvec3 v;
  size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const size_t comma = i < 2 ? text.find(',', start) : text.size();
    const auto c =
        comma == std::string::npos ? std::nullopt : finiteNumber(text.substr(start, comma - start));
    if (!c || (i == 2 && text.find(',', start) != std::string::npos))
      throw UsageError(option + ": expected X,Y,Z of finite numbers, got '" + text + "'");
    v[i] = *c;
    start = comma + 1;
  }
  return v;
}

glm::dvec3 parseVec3(const std::string& text, const std::string& option, double lo, double hi) {
  const glm::dvec3 v = parseVec3(text, option);
  for (int i = 0; i < 3; ++i) {
    if (v[i] < lo || v[i] > hi)
      throw UsageError(option + ": every component must be in [" + number(lo) + ", " + number(hi) +
                       "], got '" + text + "'");
  }
  return v;
}

void refuseOverwrite(const std::filesystem::path& output,
                     std::span<const std::filesystem::path> inputs, const std::string& option) {
  if (const auto in = sameFileAs(output, inputs)) {
    throw UsageError(option + " " + output.string() + ": is the input " + in->string() +
                     " (the same file); refusing to write over an input");
  }
}

void refuseUnwritable(const std::filesystem::path& output, const std::string& option) {
  if (const auto why = notWritable(output))
    throw UsageError(option + " " + output.string() + ": cannot be written: " + *why);
}

}  // namespace tessera::cli
