// `tessera-lod ao`: ambient occlusion of range scans into a point store (ambient_occlusion.h).
#include <tessera/lod/ambient_occlusion.h>

#include <chrono>

#include <tessera/core/file_checks.h>
#include <tessera/core/progress.h>

namespace tessera::lod {
namespace {

double since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

AoStoreReport buildStoreWithAo(const std::vector<std::filesystem::path>& inputs,
                               const std::filesystem::path& output, AoMethod method,
                               const AoOptions& options, BuildOptions build) {
  AoStoreReport r;
  std::vector<uint8_t> bytes;
  for (const std::filesystem::path& input : inputs) {
    auto t = std::chrono::steady_clock::now();
    RangeMapOptions ro;
    ro.threads = options.threads;
    ScanSet set = loadScans(input, ro);
    const AoOptions o = resolveAoOptions(set, options);
    r.resolved = o;
    r.scans += set.maps.size();
    r.points += set.size();
    r.seconds_load += since(t);

    t = std::chrono::steady_clock::now();
    {
      Progress progress("ao 1/2 ssao", set.maps.size(), " scans", build.quiet);
      for (size_t j = 0; j < set.maps.size(); ++j) {
        computeSsao(set.maps[j], uint32_t(j), o);
        progress.add(1);
      }
    }
    r.seconds_ssao += since(t);

    t = std::chrono::steady_clock::now();
    std::vector<float> ao;
    {
      Progress progress("ao 2/2 integrate", set.maps.size(), " scans", build.quiet);
      if (method == AoMethod::kMvao) {
        for (auto& m : set.maps) {
          computeBorders(m, o.threads);
          progress.add(1);
        }
        ao = integrateMvao(set, o);
      } else if (method == AoMethod::kGrid) {
        ao = gridMvao(set, o);
        progress.add(set.maps.size());
      } else {
        ao = ownSsao(set);
        progress.add(set.maps.size());
      }
    }
    r.seconds_integrate += since(t);
    for (float v : ao) bytes.push_back(aoByte(v));
  }
  build.ambient_occlusion = bytes;
  r.build = buildStore(inputs, output, build);
  return r;
}

AoStoreReport buildStoreWithAo(const std::filesystem::path& scans,
                               const std::filesystem::path& output, AoMethod method,
                               const AoOptions& options, BuildOptions build) {
  return buildStoreWithAo(std::vector<std::filesystem::path>{scans}, output, method, options,
                          std::move(build));
}

}  // namespace tessera::lod
