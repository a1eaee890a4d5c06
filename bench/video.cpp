// bench/video: the video insets on this machine.
//
//  1. Codec cost per stream: the test pattern through the real H.264 encoder (libx264,
//     ultrafast, zerolatency, intra refresh every 0.5 s, the default caps: 1000 kbit/s at
//     640x480, 2500 kbit/s at 1280x720) and FFmpeg's decoder, 30 frames/s: thread CPU per
//     picture to encode (RGBA -> YUV included) and to decode (YUV -> RGBA included), the share
//     of one core a 30 frames/s stream takes each way, the bitrate and the PSNR of what comes out.
//  2. Glass-to-glass latency on loopback, a light wall: tessera-master (60 frames/s at most) with
//     one 800x600 tile and one tessera-node, a tessera-site sending the test pattern (without
//     rendering), the inset pinned to the screen (640 pixels wide). A wall screenshot every
//     0.5 s (each one stalls the master's loop while it writes the PNG, and the frames after it
//     carry the backlog: the next screenshot comes once that has passed); each one's burned-in
//     clock is read back and compared with the moment the master
//     swapped that frame (the master's "swapped at unix ms"): the site's capture, encoding,
//     the site link, the master's wait for its next frame, the frame message, decoding, the
//     upload and the wall frame that draws it (with its read-back) are all in it; the display's
//     own scan-out is not. The wall's own frame time is stated beside it (the master's frame_ms
//     and the node's render_ms from --stats).
//
//   video [--seconds S] [--out DIR]
//
// Writes DIR/video_codec.csv, DIR/video_latency.csv, DIR/video_summary.csv and DIR/video.png.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <tessera/collab/curve.h>
#include <tessera/media/video_packet.h>
#include <tessera/media/video_pattern.h>
#include <tessera/core/cli.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/image.h>

#include "../tests/support/process.h"
#include "../tests/support/site_scripts.h"
#include "bench_stats.h"

namespace {

using tessera::bench::percentile;
using tessera::bench::threadCpuSeconds;

namespace fs = std::filesystem;
using namespace tessera;
using test::Process;

struct Size {
  int width, height, kbps;
  std::string name() const { return std::to_string(width) + "x" + std::to_string(height); }
};

struct CodecRow {
  Size size;
  double encode_ms = 0, decode_ms = 0, kbps = 0, psnr = 0;
};

CodecRow codecCost(const Size& size, int frames) {
  media::VideoSettings s;
  s.width = size.width;
  s.height = size.height;
  s.kbps = size.kbps;
  media::VideoSender sender(s, 1);
  media::VideoReceiver receiver;
  media::VideoPicture picture;
  double encode = 0, decode = 0, psnr = 0;
  size_t bytes = 0;
  int measured = 0;
  for (int f = 0; f < frames; ++f) {
    media::drawTestPattern(picture, s.width, s.height, {uint32_t(f), uint32_t(40 * f)});
    double t = threadCpuSeconds();
    const auto packets = sender.send(picture);
    encode += threadCpuSeconds() - t;
    t = threadCpuSeconds();
    for (const auto& b : packets) {
      bytes += b.size();
      media::VideoPacket p;
      if (!media::decodeVideoPacket(b, p)) receiver.receive(p);
    }
    decode += threadCpuSeconds() - t;
    if (f % 10 == 9) {
      psnr += media::videoPsnr(picture, receiver.picture(), 0, 0, s.width, s.height);
      ++measured;
    }
  }
  CodecRow r;
  r.size = size;
  r.encode_ms = 1000.0 * encode / frames;
  r.decode_ms = 1000.0 * decode / frames;
  r.kbps = double(bytes) * 8.0 / 1000.0 / (frames / s.fps);
  r.psnr = psnr / std::max(1, measured);
  return r;
}

/// The median of one column of the master's --stats CSV over rows of `tile` ("master" or a
/// tile's name).
double statsMedian(const fs::path& csv, const std::string& tile, const std::string& column) {
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  {
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) header.push_back(c);
  }
  const auto col = size_t(std::find(header.begin(), header.end(), column) - header.begin());
  std::vector<double> values;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    if (f.size() > col && f.size() > 3 && f[3] == tile) values.push_back(std::stod(f[col]));
  }
  return percentile(values, 0.5);
}

struct LatencyRun {
  std::vector<double> latency_ms;
  int shots = 0, unreadable = 0;
  double wall_frame_ms = 0, node_render_ms = 0, site_kbps = 0, site_encode_ms = 0;
  double load = 0;  ///< the machine's 1-minute load average at the end (other work competes)
};

/// The 1-minute load average (/proc/loadavg), 0 when unknown.
double loadAverage() {
  std::ifstream in("/proc/loadavg");
  double load = 0;
  in >> load;
  return load;
}

LatencyRun glassToGlass(const Size& size, const fs::path& work, const std::string& bin,
                        double seconds) {
  fs::remove_all(work);
  fs::create_directories(work);
  const collab::KeyPair master_keys = collab::generateKeyPair(),
                        site_keys = collab::generateKeyPair();
  collab::writeKeyFile(work / "master.key", master_keys);
  collab::writeKeyFile(work / "site.key", site_keys);
  std::ofstream(work / "allow.txt") << site_keys.public_key << "  bench site\n";
  std::ofstream(work / "wall.json")
      << R"({"name": "light wall", "tiles": [{"name": "tile", "x": 0, "y": 0, "width": 0.8, )"
      << R"("height": 0.6, "pixelWidth": 800, "pixelHeight": 600}], )"
      << R"("eye": {"x": 0.4, "y": 0.3, "z": 1.5}})";
  const std::string camera = test::cameraJson({0, 0, 1}, {0, 0, 0});
  std::ofstream(work / "scene.json") << R"({"nodes": [], "camera": )" << camera << "}";
  std::vector<std::string> argv = test::masterWithSites(
      bin + "/master/tessera-master", work, work, seconds, camera,
      {"--out-dir", work.string(), "--video-screen", "0.1,0.1,0.8", "--video-cap", "20000"});
  test::setOption(argv, "--max-fps", "60");
  test::writeHoldWithScreenshots(work / "hold.json", camera, seconds, 2.0, 0.5);
  Process master(argv, work / "master.log");
  LatencyRun r;
  if (!master.waitFor("remote sites join on (tcp://\\S+)", 30)) {
    std::cerr << "video: the master did not start:\n" << master.output();
    return r;
  }
  std::smatch m;
  const std::string out = master.output();
  std::regex_search(out, m, std::regex("listening on (tcp://\\S+)"));
  const std::string wall = m[1];
  std::regex_search(out, m, std::regex("remote sites join on tcp://[^:]+:(\\d+)"));
  const std::string sites = "tcp://127.0.0.1:" + m[1].str();
  Process node(
      {bin + "/render_node/tessera-node", "--master", wall, "--headless", "--tile", "tile"},
      work / "node.log");
  std::ofstream(work / "still.json") << R"({"actions": []})";
  Process site(test::headlessSite(bin + "/collab/tessera-site", sites, master_keys.public_key,
                                  "bench site", work / "site.key", work, work / "still.json",
                                  {"--no-render", "--video", "test", "--video-size", size.name(),
                                   "--video-kbps", std::to_string(size.kbps)}),
               work / "site.log");
  (void)master.wait(seconds + 120);
  (void)node.wait(15);
  (void)site.wait(15);
  const std::string log = master.output();
  // The inset: 0.8 of the wall wide from (80, 60) down, its height the picture's aspect.
  const int w = 640, h = 640 * size.height / size.width, x = 80, y = 600 - 60 - h;
  const std::regex wrote("frame (\\d+): wrote (\\S+) \\(");
  for (auto it = std::sregex_iterator(log.begin(), log.end(), wrote); it != std::sregex_iterator();
       ++it) {
    ++r.shots;
    std::smatch s;
    const std::string frame = (*it)[1];
    if (!std::regex_search(log, s, std::regex("frame " + frame + ": swapped at unix ms ([0-9.]+)")))
      continue;
    const double swapped = std::stod(s[1]);
    const render::Image image = render::readPng((*it)[2].str());
    const auto code = media::readTestPattern(image.rgba.data(), int(image.width), x, y, w, h);
    if (!code) {
      ++r.unreadable;
      continue;
    }
    r.latency_ms.push_back(
        double(media::patternDelayMs(code->time_ms, uint32_t(uint64_t(swapped) & 0xFFFFFFFFu))));
  }
  r.load = loadAverage();
  r.wall_frame_ms = statsMedian(work / "stats.csv", "master", "frame_ms");
  r.node_render_ms = statsMedian(work / "stats.csv", "tile", "render_ms");
  const std::string site_log = site.output();
  if (std::regex_search(site_log, m,
                        std::regex("\\(([0-9.]+) kbit/s\\), ([0-9.]+) ms to encode each"))) {
    r.site_kbps = std::stod(m[1]);
    r.site_encode_ms = std::stod(m[2]);
  }
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  tessera::render::timePasses(true);  // the per-pass figures
  return cli::runMain("video", [&] {
    CLI::App app{"video: H.264 inset cost per stream and glass-to-glass latency on loopback"};
    double seconds = 30;
    std::string out = TESSERA_BENCH_RESULTS_DIR;
    app.add_option("--seconds", seconds, "Seconds of each glass-to-glass run")
        ->check(cli::finiteRange(4, 600))
        ->capture_default_str();
    app.add_option("--out", out, "Results folder")->capture_default_str();
    if (const auto code = cli::parse(app, argc, argv, "video")) return *code;
    fs::create_directories(out);
    const std::string bin = fs::canonical("/proc/self/exe").parent_path().parent_path().string();
    const std::vector<Size> sizes = {{640, 480, 1000}, {1280, 720, 2500}};

    std::ofstream codec(fs::path(out) / "video_codec.csv");
    codec << "size,kbps_cap,encode_ms,decode_ms,encode_core_share_30fps,decode_core_share_30fps,"
             "bitrate_kbps,psnr_db\n";
    std::vector<CodecRow> rows;
    for (const Size& s : sizes) {
      const CodecRow r = codecCost(s, 300);
      rows.push_back(r);
      codec << s.name() << "," << s.kbps << "," << r.encode_ms << "," << r.decode_ms << ","
            << r.encode_ms * 30 / 1000 << "," << r.decode_ms * 30 / 1000 << "," << r.kbps << ","
            << r.psnr << "\n";
      std::printf(
          "%s: encode %.2f ms, decode %.2f ms per picture (%.0f%% and %.0f%% of a core "
          "at 30 frames/s), %.0f kbit/s, PSNR %.1f dB\n",
          s.name().c_str(), r.encode_ms, r.decode_ms, r.encode_ms * 3, r.decode_ms * 3, r.kbps,
          r.psnr);
    }
    codec.close();

    std::ofstream lat(fs::path(out) / "video_latency.csv");
    lat << "size,sample,latency_ms\n";
    std::ofstream sum(fs::path(out) / "video_summary.csv");
    sum << "size,screenshots,unreadable,latency_median_ms,latency_p99_ms,wall_frame_ms_median,"
           "node_render_ms_median,site_kbps,site_encode_ms,load_average\n";
    std::vector<LatencyRun> runs;
    for (const Size& s : sizes) {
      const LatencyRun r =
          glassToGlass(s, fs::path(out) / ("video-work-" + s.name()), bin, seconds);
      runs.push_back(r);
      for (size_t i = 0; i < r.latency_ms.size(); ++i)
        lat << s.name() << "," << i << "," << r.latency_ms[i] << "\n";
      sum << s.name() << "," << r.shots << "," << r.unreadable << ","
          << percentile(r.latency_ms, 0.5) << "," << percentile(r.latency_ms, 0.99) << ","
          << r.wall_frame_ms << "," << r.node_render_ms << "," << r.site_kbps << ","
          << r.site_encode_ms << "," << r.load << "\n";
      std::printf(
          "%s glass-to-glass (loopback, light wall): median %.0f ms, p99 %.0f ms over %zu "
          "screenshots (%d unreadable); the wall's frame %.1f ms (node render %.1f ms); "
          "site %.0f kbit/s, %.1f ms to encode; load average %.1f on %u cores\n",
          s.name().c_str(), percentile(r.latency_ms, 0.5), percentile(r.latency_ms, 0.99),
          r.latency_ms.size(), r.unreadable, r.wall_frame_ms, r.node_render_ms, r.site_kbps,
          r.site_encode_ms, r.load, std::thread::hardware_concurrency());
    }
    lat.close();
    sum.close();

    const fs::path res = fs::path(out);
    const double goal = 100.0 + runs[0].wall_frame_ms;
    double codec_top = 1.0;  // room above the tallest bar for the key
    for (const CodecRow& r : rows) codec_top = std::max(codec_top, 1.4 * r.encode_ms);
    std::ofstream gp(res / "video.gp");
    gp << "set terminal pngcairo noenhanced size 1300,480 font ',10'\n"
       << "set output '" << (res / "video.png").string() << "'\n"
       << "set datafile separator ','\nset multiplot layout 1,2\nset grid\n"
       << "set title 'Glass-to-glass on loopback (light wall: 1 tile 800x600, 30 frames/s "
          "test pattern)'\nset xlabel 'screenshot'\nset ylabel 'ms'\nset yrange [0:*]\n"
       << "set key bottom right\n"
       << "plot '" << (res / "video_latency.csv").string()
       << "' skip 1 using (strcol(1) eq '640x480' ? $2 : 1/0):3 with linespoints pt 7 title "
          "'640x480', "
          "\\\n  '' skip 1 using (strcol(1) eq '1280x720' ? $2 : 1/0):3 with linespoints pt 6 "
          "title "
          "'1280x720', \\\n  "
       << goal << " with lines dt 2 lw 2 lc rgb '#d62728' title 'goal: 100 ms + one wall frame ("
       << int(goal + 0.5) << " ms)'\n"
       << "set title 'Codec CPU per picture (one thread, 2-core machine)'\n"
       << "set xlabel ''\nset ylabel 'ms per picture'\nset yrange [0:" << codec_top
       << "]\nset key top left\n"
       << "set style data histogram\nset style histogram cluster gap 1\n"
       << "set style fill solid 0.7\nset boxwidth 0.9\n"
       << "plot '" << (res / "video_codec.csv").string()
       << "' skip 1 using 3:xtic(1) title 'encode (libx264 ultrafast + RGBA->YUV)', '' skip 1 "
          "using 4 title 'decode (h264 + YUV->RGBA)'\n"
       << "unset multiplot\n";
    gp.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + (res / "video.gp").string() + "'").c_str()))
      std::cerr << "video: gnuplot failed; the CSVs are still there\n";
    else
      std::cerr << "chart: " << (res / "video.png").string() << "\n";
    return 0;
  });
}
