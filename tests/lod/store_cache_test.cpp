// The store cache (lod/store_cache.h) shared by processes: four tessera-render processes, as the
// render nodes of one host would, convert the same scan into one cache at once. One entry is
// built, every process draws from it, nothing temporary is left. And an entry is keyed by the
// input's size and time, so a changed input is never taken for the cached one. tessera-render
// --preview writes a raw scan's preview before it converts the scan, and none once it is cached.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <iterator>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <tessera/lod/store_cache.h>

#include "../support/process.h"
#include "../support/temp_dir.h"

namespace tessera::lod {
namespace {

namespace fs = std::filesystem;

std::string fileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// An ASCII PLY of `n` points on a wavy sheet, coloured by height.
void writeSheet(const fs::path& path, int n, uint32_t seed) {
  std::ofstream out(path);
  out << "ply\nformat ascii 1.0\nelement vertex " << n
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
         "property uchar green\nproperty uchar blue\nend_header\n";
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < n; ++i) {
    const float x = u(rng), y = u(rng), z = 0.2f * std::sin(3.0f * x) * std::cos(2.0f * y);
    out << x << " " << y << " " << z << " " << int(128 + 600 * z) << " 90 " << int(128 - 600 * z)
        << "\n";
  }
}

TEST(StoreCache, FourProcessesOnOneCacheBuildOneEntryAndAllDrawIt) {
  test::TempDir dir;
  const fs::path scan = dir / "sheet.ply", cache = dir / "cache";
  writeSheet(scan, 60000, 3);
  ::setenv("XDG_CACHE_HOME", cache.c_str(), 1);  // the children inherit it
  // Under the sanitizer pass the children are instrumented too; Mesa's own allocations are not
  // ours to check for leaks.
  ::setenv("ASAN_OPTIONS", "detect_leaks=0", 1);
  std::vector<std::unique_ptr<test::Process>> nodes;
  for (int k = 0; k < 4; ++k) {
    const fs::path png = dir / ("node" + std::to_string(k) + ".png");
    nodes.push_back(std::make_unique<test::Process>(
        std::vector<std::string>{TESSERA_RENDER_TOOL, "--model", scan.string(), "--size", "96x64",
                                 "-o", png.string()},
        dir / ("node" + std::to_string(k) + ".log")));
  }
  for (auto& p : nodes) ASSERT_EQ(p->wait(300), std::optional<int>(0)) << p->output();
  ::unsetenv("XDG_CACHE_HOME");

  // One entry and its lock; no .partial, no private build names, no temporary folders.
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(cache / "tessera")) names.insert(e.path().filename());
  ASSERT_EQ(names.size(), 2u) << [&] {
    std::string s;
    for (const auto& n : names) s += n + " ";
    return s;
  }();
  const std::string entry = *names.begin();
  EXPECT_TRUE(entry.ends_with(".tlod")) << entry;
  EXPECT_EQ(*names.rbegin(), entry + ".lock");
  // One process converted; the others found the entry (after waiting for it, or later).
  int converted = 0;
  for (auto& p : nodes) converted += p->output().find("converting") != std::string::npos;
  EXPECT_EQ(converted, 1);
  // The same picture on every node.
  const std::string first = fileBytes(dir / "node0.png");
  ASSERT_GT(first.size(), 100u);
  for (int k = 1; k < 4; ++k)
    EXPECT_EQ(fileBytes(dir / ("node" + std::to_string(k) + ".png")), first) << k;
}

TEST(StoreCache, AChangedInputIsANewEntryAndAMissingOneIsNamed) {
  test::TempDir dir;
  const fs::path scan = dir / "sheet.ply";
  writeSheet(scan, 100, 4);
  ::setenv("XDG_CACHE_HOME", (dir / "cache").c_str(), 1);
  const fs::path before = cachedStorePath(scan, "test");
  fs::last_write_time(scan, fs::last_write_time(scan) + std::chrono::seconds(5));
  EXPECT_NE(cachedStorePath(scan, "test"), before) << "the same entry for a newer input";
  try {
    cachedStorePath(dir / "gone.ply", "test");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("gone.ply"), std::string::npos) << e.what();
  }
  ::unsetenv("XDG_CACHE_HOME");
}

TEST(StoreCache, TesseraRenderWritesARawScansPreviewBeforeItsWholeStoresPicture) {
  test::TempDir dir;
  ::setenv("XDG_CACHE_HOME", (dir / "cache").c_str(), 1);  // the child inherits it
  ::setenv("ASAN_OPTIONS", "detect_leaks=0", 1);
  const std::string las = std::string(TESSERA_DATA_DIR) + "/lidar/autzen_trim.las";
  int runs = 0;
  auto render = [&](const std::vector<std::string>& more) {
    std::vector<std::string> args{TESSERA_RENDER_TOOL, "--model", las, "--size", "160x90"};
    args.insert(args.end(), more.begin(), more.end());
    test::Process p(args, dir / ("render-" + std::to_string(runs++) + ".log"));
    const std::optional<int> code = p.wait(300);
    return std::make_pair(code.value_or(-1), p.output());
  };
  const fs::path first = dir / "first.png", last = dir / "last.png";
  const auto [code, out] =
      render({"--preview", first.string(), "--preview-points", "10000", "-o", last.string()});
  ASSERT_EQ(code, 0) << out;
  // The preview of every 11th record, written before the whole store is converted.
  const size_t preview = out.find("preview of 10000 points");
  const size_t wrote_first = out.find("wrote " + first.string());
  const size_t converting = out.find("converting");
  const size_t wrote_last = out.find("wrote " + last.string());
  ASSERT_NE(preview, std::string::npos) << out;
  ASSERT_NE(wrote_last, std::string::npos) << out;
  EXPECT_LT(wrote_first, converting) << out;
  EXPECT_LT(converting, wrote_last) << out;
  EXPECT_GT(fs::file_size(first), 100u);
  EXPECT_NE(fileBytes(first), fileBytes(last));  // a coarser picture of the same view
  // Its store cached, the scan needs no preview: the first picture is the final one.
  const auto [again, again_out] = render({"--preview", first.string(), "-o", last.string()});
  ASSERT_EQ(again, 0) << again_out;
  EXPECT_NE(again_out.find("no scan needed a preview"), std::string::npos) << again_out;
  EXPECT_EQ(fileBytes(first), fileBytes(last));
  // The preview and the window do not go together: a bad command line, exit 2.
  const auto [window, window_out] = render({"--preview", first.string(), "--window"});
  EXPECT_EQ(window, 2) << window_out;
  EXPECT_NE(window_out.find("--preview"), std::string::npos) << window_out;
  ::unsetenv("XDG_CACHE_HOME");
}

}  // namespace
}  // namespace tessera::lod
