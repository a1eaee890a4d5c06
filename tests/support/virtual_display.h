// A virtual X server for the tests that drive windows as a user would (the master's console,
// tessera-site --window): Xvfb on a free display and xdotool.
#pragma once

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "command.h"
#include "process.h"

namespace tessera::test {

/// A virtual X server (Xvfb) on a free display, with xdotool to drive its windows as a user's
/// mouse and keys would; DISPLAY is set for the processes the test starts meanwhile.
struct VirtualDisplay {
  static constexpr const char* kXvfb = "/usr/bin/Xvfb";
  static constexpr const char* kXdotool = "/usr/bin/xdotool";
  static bool available() {
    return std::filesystem::exists(kXvfb) && std::filesystem::exists(kXdotool);
  }

  explicit VirtualDisplay(const std::filesystem::path& log) {
    int n = 60 + int(getpid() % 300);
    while (std::filesystem::exists("/tmp/.X11-unix/X" + std::to_string(n))) ++n;
    name = ":" + std::to_string(n);
    server = std::make_unique<Process>(
        std::vector<std::string>{kXvfb, name, "-screen", "0", "1024x768x24", "-nolisten", "tcp"},
        log);
    for (int i = 0; i < 100 && !std::filesystem::exists("/tmp/.X11-unix/X" + std::to_string(n));
         ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    setenv("DISPLAY", name.c_str(), 1);
  }
  ~VirtualDisplay() { unsetenv("DISPLAY"); }

  /// xdotool ARGS on this display; its output.
  std::string operator()(const std::string& args) const {
    const auto r = tessera::test::runCommand("DISPLAY=" + name + " " + kXdotool + " " + args);
    EXPECT_EQ(r.code, 0) << args << ": " << r.out;
    return r.out;
  }
  /// The first window whose title matches `title`, waiting up to 10 s ("" if none).
  std::string window(const std::string& title) const {
    for (int i = 0; i < 100; ++i) {
      const auto r = tessera::test::runCommand("DISPLAY=" + name + " " + kXdotool +
                                               " search --name '" + title + "'");
      if (r.code == 0 && !r.out.empty()) return r.out.substr(0, r.out.find('\n'));
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return "";
  }
  /// A right-button drag along a row of the window, from x0 to x1 at y.
  void rightDrag(const std::string& wid, int x0, int x1, int y) const { drag(wid, 3, x0, x1, y); }
  /// A left drag around the box (x0, y0)-(x1, y1), back near its start (a lasso), 80 ms a side.
  void boxDrag(const std::string& wid, int x0, int y0, int x1, int y1) const {
    auto move = [&](int x, int y) {
      (*this)("mousemove --window " + wid + " " + std::to_string(x) + " " + std::to_string(y));
    };
    (*this)("mousemove --window " + wid + " " + std::to_string(x0) + " " + std::to_string(y0) +
            " mousedown 1");
    for (const auto& [x, y] : {std::pair{x1, y0}, {x1, y1}, {x0, y1}, {x0, y0 + 5}}) {
      std::this_thread::sleep_for(std::chrono::milliseconds(80));
      move(x, y);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(80));
    (*this)("mouseup 1");
  }
  /// Types `text` into the Dear ImGui field that has the keyboard, after giving the form a
  /// moment to open, then Enter held over a frame (ImGui 1.86 reads keys as held, not as
  /// events, so a key shorter than a slow llvmpipe frame could be missed).
  void typeAndEnter(const std::string& wid, const std::string& text) const {
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    (*this)("type --window " + wid + " --delay 60 '" + text + "'");
    (*this)("keydown --window " + wid + " Return");
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    (*this)("keyup --window " + wid + " Return");
  }
  /// A horizontal drag with mouse `button` (1 left, 3 right) from x0 to x1 along row y.
  void drag(const std::string& wid, int button, int x0, int x1, int y) const {
    const std::string b = std::to_string(button);
    (*this)("mousemove --window " + wid + " " + std::to_string(x0) + " " + std::to_string(y) +
            " mousedown " + b);
    for (int x = x0 + 10; x <= x1; x += 10) {
      (*this)("mousemove --window " + wid + " " + std::to_string(x) + " " + std::to_string(y));
      std::this_thread::sleep_for(std::chrono::milliseconds(60));
    }
    (*this)("mouseup " + b);
  }

  std::string name;
  std::unique_ptr<Process> server;
};

}  // namespace tessera::test
