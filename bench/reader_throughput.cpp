// reader_throughput: points per second the streaming readers deliver from files in the page
// cache, next to a plain read() of the same bytes in the same run (the ceiling for a reader).
// Inputs are tiled from the real Autzen LiDAR scan and generated once into OUT/inputs (PLY, LAS,
// and LAZ pointwise and layered, decoded on 1 and on 2 threads); the real Autzen LAS and LAZ and
// the real E57 bunny are measured too. Prints CSV on stdout, writes OUT/reader_throughput.csv and
// draws OUT/reader_throughput.png with gnuplot. Goal: >= 30 M points/s for binary PLY and LAS.
//
// --build-points N also builds a store from a LAS file and from its LAZ twin (N points, the
// builds alternated, best of --repeat) and writes OUT/laz_build.csv and OUT/laz_build.png.
// Goals: the LAZ build at least 0.5x as fast as the LAS build, LAZ decoding at least 1.8x
// faster on 2 threads than on 1.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include <tessera/core/progress.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_writer.h>
#include <tessera/lod/store_builder.h>

namespace {

namespace fs = std::filesystem;
using namespace tessera::lod;

constexpr double kGoalMPointsPerS = 30.0;
constexpr size_t kPlainReadBuffer = size_t(4) << 20;  // same chunk size as the readers' reads
constexpr const char* kCsvName = "reader_throughput.csv";

struct Input {
  std::string format;  ///< label in the CSV and on the chart
  fs::path file;
  uint64_t points = 0;  ///< points in one pass over the file
  uint64_t bytes = 0;   ///< file size
  int passes = 1;       ///< passes per measurement (a tiny file is read many times)
  unsigned threads = 0;  ///< LAZ: chunks decoded at once (0: the reader's default)
};

struct Result {
  Input input;
  double plain_s = 0.0;   ///< best time for `passes` plain reads
  double reader_s = 0.0;  ///< best time for `passes` reader drains
  uint64_t points() const { return input.points * uint64_t(input.passes); }
  uint64_t bytes() const { return input.bytes * uint64_t(input.passes); }
  double plainMpts() const { return double(points()) / plain_s / 1e6; }
  double readerMpts() const { return double(points()) / reader_s / 1e6; }
  double readerMBs() const { return double(bytes()) / reader_s / 1e6; }
};

double seconds(const std::function<void()>& work) {
  auto start = std::chrono::steady_clock::now();
  work();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// read() of the whole file into a 4 MiB buffer. Returns a checksum so every read counts.
uint64_t plainRead(const fs::path& path, std::vector<uint8_t>& buffer) {
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0)
    throw std::runtime_error("cannot open " + path.string() + ": " + std::strerror(errno));
  uint64_t sum = 0;
  for (;;) {
    ssize_t got = ::read(fd, buffer.data(), buffer.size());
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) {
      int err = errno;
      ::close(fd);
      throw std::runtime_error("cannot read " + path.string() + ": " + std::strerror(err));
    }
    if (got == 0) break;
    sum += buffer[0] + buffer[size_t(got) - 1];
  }
  ::close(fd);
  return sum;
}

/// Drains every batch of the reader, touching each position. Returns the sum of coordinates.
double drainReader(const Input& in) {
  ReaderOptions options;
  options.decode_threads = in.threads;
  auto reader = openPointReader(in.file, options);
  PointBatch batch;
  double sum = 0.0;
  uint64_t n = 0;
  while (reader->next(batch)) {
    for (const glm::dvec3& p : batch.positions) sum += p.x + p.y + p.z;
    n += batch.size();
  }
  if (n != in.points || reader->stats().skippedTotal() != 0) {
    throw std::runtime_error(in.file.string() + ": read " + std::to_string(n) +
                             " points, expected " + std::to_string(in.points));
  }
  return sum;
}

/// The whole real scan in one batch (positions relative to `origin`).
PointBatch readAll(const fs::path& path, glm::dvec3& origin) {
  auto reader = openPointReader(path);
  origin = reader->info().origin;
  PointBatch all, batch;
  all.reset(reader->info().attributes);
  while (reader->next(batch)) {
    for (size_t i = 0; i < batch.size(); ++i) all.appendFrom(batch, i);
  }
  return all;
}

/// `n` points made of copies of `scan` laid side by side on a square grid of tiles: a survey
/// `sqrt(copies)` times wider with real point spacing, colours and intensities.
PointBatch tiledCloud(const PointBatch& scan, uint64_t n) {
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  for (const glm::dvec3& p : scan.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const uint64_t copies = (n + scan.size() - 1) / scan.size();
  const uint64_t columns = uint64_t(std::ceil(std::sqrt(double(copies))));
  PointBatch out;
  out.reset(scan.attributes);
  out.resize(size_t(n));
  for (uint64_t i = 0; i < n; ++i) {
    uint64_t copy = i / scan.size(), src = i % scan.size();
    glm::dvec3 tile((hi.x - lo.x) * double(copy % columns), (hi.y - lo.y) * double(copy / columns),
                    0.0);
    out.positions[i] = scan.positions[src] + tile;
    out.colors[i] = scan.colors[src];
    out.intensities[i] = scan.intensities[src];
    out.classifications[i] = scan.classifications[src];
  }
  return out;
}

/// Writes `cloud` (positions relative to the scan origin) as a PLY in local coordinates, where
/// float keeps about a millimetre, with colour only: the common shape of scanned PLY clouds.
std::function<void(PointBatch&, const fs::path&)> plyWriter(PlyEncoding encoding, bool doubles) {
  return [=](PointBatch& cloud, const fs::path& path) {
    PlyWriteOptions o;
    o.encoding = encoding;
    o.double_positions = doubles;
    const AttributeMask all = cloud.attributes;
    cloud.attributes = kColor;
    writePly(path, cloud, glm::dvec3(0.0), o);
    cloud.attributes = all;
  };
}

/// LAS or LAZ of `format` (3: LAS 1.2, 7: LAS 1.4) at the Autzen survey's own 1 cm.
std::function<void(PointBatch&, const fs::path&)> lasWriter(const glm::dvec3& origin, int format,
                                                            bool laz) {
  return [=](PointBatch& cloud, const fs::path& path) {
    LasWriteOptions o;
    o.scale = glm::dvec3(0.01);
    o.point_format = format;
    o.minor_version = format >= 6 ? 4 : 2;
    o.laz = laz;
    writeLas(path, cloud, origin, o);
  };
}

/// Writes the benchmark inputs into `dir` unless a previous run left them there.
std::vector<Input> prepareInputs(const fs::path& dir, uint64_t n, bool quiet) {
  const fs::path autzen = fs::path(TESSERA_DATA_DIR) / "lidar" / "autzen_trim.las";
  glm::dvec3 origin;
  PointBatch scan = readAll(autzen, origin);
  const uint64_t n_ascii = std::max<uint64_t>(1, n / 10);
  const std::string tag = std::to_string(n);
  struct Generated {
    Input input;
    std::function<void(PointBatch&, const fs::path&)> write;
  };
  std::vector<Generated> generated = {
      {{"PLY binary LE float", dir / ("le_float_" + tag + ".ply"), n},
       plyWriter(PlyEncoding::kBinaryLittleEndian, false)},
      {{"PLY binary LE double", dir / ("le_double_" + tag + ".ply"), n},
       plyWriter(PlyEncoding::kBinaryLittleEndian, true)},
      {{"PLY binary BE float", dir / ("be_float_" + tag + ".ply"), n},
       plyWriter(PlyEncoding::kBinaryBigEndian, false)},
      {{"PLY ASCII", dir / ("ascii_" + std::to_string(n_ascii) + ".ply"), n_ascii},
       plyWriter(PlyEncoding::kAscii, false)},
      {{"LAS 1.2 format 3", dir / ("las12_fmt3_" + tag + ".las"), n}, lasWriter(origin, 3, false)},
      {{"LAZ 1.2 format 3 (1 thread)", dir / ("laz12_fmt3_" + tag + ".laz"), n, 0, 1, 1},
       lasWriter(origin, 3, true)},
      {{"LAZ 1.2 format 3 (2 threads)", dir / ("laz12_fmt3_" + tag + ".laz"), n, 0, 1, 2},
       lasWriter(origin, 3, true)},
      {{"LAZ 1.4 format 7 (1 thread)", dir / ("laz14_fmt7_" + tag + ".laz"), n, 0, 1, 1},
       lasWriter(origin, 7, true)},
      {{"LAZ 1.4 format 7 (2 threads)", dir / ("laz14_fmt7_" + tag + ".laz"), n, 0, 1, 2},
       lasWriter(origin, 7, true)},
  };
  fs::create_directories(dir);
  std::vector<Input> inputs;
  PointBatch cloud;
  for (Generated& g : generated) {
    // Writers write to a temporary name and rename: an existing file is complete.
    if (!fs::exists(g.input.file)) {
      if (!quiet) std::cerr << "generating " << g.input.file.string() << "\n";
      if (cloud.size() != g.input.points) cloud = tiledCloud(scan, g.input.points);
      g.write(cloud, g.input.file);
    }
    g.input.bytes = fs::file_size(g.input.file);
    inputs.push_back(g.input);
  }
  // The real files are small: read them often enough to measure a quarter of the generated
  // points. Autzen's LAZ twin was written by LASzip itself.
  const int passes = int(std::max<uint64_t>(10, n / 4 / scan.size()));
  inputs.push_back({"LAS autzen_trim (real)", autzen, scan.size(), fs::file_size(autzen), passes});
  const fs::path autzen_laz = fs::path(TESSERA_DATA_DIR) / "lidar" / "autzen_trim.laz";
  inputs.push_back({"LAZ autzen_trim (real; LASzip)", autzen_laz, scan.size(),
                    fs::file_size(autzen_laz), passes});
  const fs::path bunny_e57 = fs::path(TESSERA_DATA_DIR) / "e57" / "bunnyDouble.e57";
  const uint64_t e57_points = 30571;
  inputs.push_back({"E57 bunnyDouble (real)", bunny_e57, e57_points, fs::file_size(bunny_e57),
                    int(std::max<uint64_t>(10, n / 4 / e57_points))});
  return inputs;
}

/// Best of `repeat` for both ways of reading `in`, alternated so both see the same conditions.
Result measure(const Input& in, int repeat, std::vector<uint8_t>& buffer,
               tessera::Progress& progress) {
  volatile uint64_t byte_sum = plainRead(in.file, buffer);  // warms the page cache
  volatile double position_sum = 0.0;
  auto plain = [&] {
    for (int p = 0; p < in.passes; ++p) byte_sum = byte_sum + plainRead(in.file, buffer);
  };
  auto reader = [&] {
    for (int p = 0; p < in.passes; ++p) position_sum = position_sum + drainReader(in);
  };
  Result r{in, std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  for (int rep = 0; rep < repeat; ++rep) {
    r.plain_s = std::min(r.plain_s, seconds(plain));
    progress.add(1);
    r.reader_s = std::min(r.reader_s, seconds(reader));
    progress.add(1);
  }
  return r;
}

std::string csvLine(const Result& r) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "%s,%s,%llu,%llu,%.6f,%.6f,%.2f,%.2f,%.1f,%.4f",
                r.input.format.c_str(), r.input.file.string().c_str(),
                static_cast<unsigned long long>(r.points()),
                static_cast<unsigned long long>(r.bytes()), r.plain_s, r.reader_s, r.plainMpts(),
                r.readerMpts(), r.readerMBs(), r.readerMpts() / r.plainMpts());
  return buf;
}

/// Grouped bars (plain read vs reader, M points/s, log scale) with the goal as a line.
bool drawChart(const fs::path& out, size_t formats, uint64_t n, int repeat, bool quiet) {
  const fs::path script = out / "reader_throughput.gp";
  std::ofstream gp(script);
  gp << "set terminal pngcairo noenhanced size 1400,700 font ',10'\n"
     << "set output '" << (out / "reader_throughput.png").string() << "'\n"
     << "set datafile separator ','\n"
     << "set title 'Reader throughput from the page cache (" << tessera::humanCount(double(n))
     << " points per binary file, best of " << repeat << ")'\n"
     << "set style data histogram\n"
     << "set style histogram clustered gap 1\n"
     << "set style fill solid 0.85 border -1\n"
     << "set boxwidth 0.9\n"
     << "set logscale y\n"
     << "set yrange [0.5:*]\n"
     << "set ylabel 'M points/s (log scale)'\n"
     << "set grid ytics\n"
     << "set key outside top center horizontal\n"
     << "set xtics nomirror rotate by -25\n"
     << "set bmargin 7\n"
     << "set xrange [-0.6:" << double(formats) - 0.4 << "]\n"
     << "plot '" << (out / kCsvName).string() << "' skip 1 using 7:xtic(1) lc rgb '#9e9e9e' "
     << "title 'plain read() of the same bytes', \\\n"
     << "  '' skip 1 using 8 lc rgb '#1f77b4' title 'reader (all batches)', \\\n"
     << "  '' skip 1 using ($0+1.0/6):8:(sprintf('%.1f', $8)) with labels offset 0,0.7 notitle, "
        "\\\n"
     << "  " << kGoalMPointsPerS
     << " with lines dt 2 lw 2 lc rgb '#d62728' title 'goal: " << kGoalMPointsPerS
     << " M points/s'\n";
  gp.close();
  std::string gnuplot = TESSERA_GNUPLOT;
  if (gnuplot.empty()) gnuplot = "gnuplot";
  std::string cmd = "'" + gnuplot + "' '" + script.string() + "'";
  if (std::system(cmd.c_str()) != 0) {
    std::cerr << "reader_throughput: gnuplot failed (" << cmd << "); the CSV is still there\n";
    return false;
  }
  if (!quiet) std::cerr << "chart: " << (out / "reader_throughput.png").string() << "\n";
  return true;
}

/// A store built from a LAS file and from its LAZ twin, alternated; LAZ decoding alone on 1 and
/// on 2 threads. Writes laz_build.csv and laz_build.png into `out`.
void measureBuilds(const fs::path& out, uint64_t n, int repeat, bool quiet) {
  const fs::path dir = out / "inputs";
  const fs::path autzen = fs::path(TESSERA_DATA_DIR) / "lidar" / "autzen_trim.las";
  const std::string tag = std::to_string(n);
  const fs::path las = dir / ("build_" + tag + ".las"), laz = dir / ("build_" + tag + ".laz");
  if (!fs::exists(las) || !fs::exists(laz)) {
    glm::dvec3 origin;
    PointBatch cloud = tiledCloud(readAll(autzen, origin), n);
    if (!quiet) std::cerr << "generating " << las.string() << " and its LAZ twin\n";
    lasWriter(origin, 3, false)(cloud, las);
    lasWriter(origin, 3, true)(cloud, laz);
  }
  struct Row {
    std::string what;
    double best = std::numeric_limits<double>::max();
  };
  std::vector<Row> rows = {{"build from LAS"}, {"build from LAZ"}, {"decode LAZ (1 thread)"},
                           {"decode LAZ (2 threads)"}};
  const fs::path store = out / "laz_build.tlod";
  BuildOptions b;
  b.quiet = true;
  tessera::Progress progress("laz_build", size_t(repeat) * rows.size(), "measurements", quiet);
  for (int rep = 0; rep < repeat; ++rep) {
    rows[0].best = std::min(rows[0].best, seconds([&] { buildStore({las}, store, b); }));
    progress.add(1);
    rows[1].best = std::min(rows[1].best, seconds([&] { buildStore({laz}, store, b); }));
    progress.add(1);
    for (unsigned t : {1u, 2u}) {
      Input in{"", laz, n, fs::file_size(laz), 1, t};
      rows[1 + t].best = std::min(rows[1 + t].best, seconds([&] { drainReader(in); }));
      progress.add(1);
    }
  }
  fs::remove(store);
  std::ofstream csv(out / "laz_build.csv");
  csv << "what,points,seconds,mpts_per_s\n";
  for (const Row& r : rows) {
    char line[256];
    std::snprintf(line, sizeof line, "%s,%llu,%.4f,%.3f", r.what.c_str(),
                  static_cast<unsigned long long>(n), r.best, double(n) / r.best / 1e6);
    csv << line << "\n";
    std::cout << line << "\n";
  }
  std::printf("LAZ build / LAS build speed: %.2f (goal >= 0.5); LAZ decoding 2 threads / 1: %.2f "
              "(goal >= 1.8)\n",
              rows[0].best / rows[1].best, rows[2].best / rows[3].best);
  csv.close();
  const fs::path script = out / "laz_build.gp";
  std::ofstream gp(script);
  gp << "set terminal pngcairo noenhanced size 900,500 font ',10'\n"
     << "set output '" << (out / "laz_build.png").string() << "'\n"
     << "set datafile separator ','\n"
     << "set title 'A store from LAS and from its LAZ twin (" << tessera::humanCount(double(n))
     << " points of tiled Autzen, best of " << repeat << ")'\n"
     << "set style fill solid 0.85 border -1\nset boxwidth 0.6\nset grid ytics\n"
     << "set ylabel 'M points/s'\nset yrange [0:*]\nset xtics nomirror\n"
     << "plot '" << (out / "laz_build.csv").string()
     << "' skip 1 using 0:4:xtic(1) with boxes lc rgb '#1f77b4' notitle, \\\n"
     << "  '' skip 1 using 0:4:(sprintf('%.2f', $4)) with labels offset 0,0.8 notitle\n";
  gp.close();
  std::string gnuplot = TESSERA_GNUPLOT;
  if (gnuplot.empty()) gnuplot = "gnuplot";
  const std::string cmd = "'" + gnuplot + "' '" + script.string() + "'";
  if (std::system(cmd.c_str()) != 0) std::cerr << "reader_throughput: gnuplot failed\n";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "reader_throughput: points/s of the PLY, LAS, LAZ and E57 readers from the page cache "
      "against a plain read() of the same bytes. Prints CSV; writes reader_throughput.csv and "
      ".png into --out (and laz_build.csv and .png with --build-points)."};
  uint64_t points = 20'000'000;
  std::string out = TESSERA_BENCH_RESULTS_DIR;
  int repeat = 3;
  bool remove_inputs = false, quiet = false;
  uint64_t build_points = 0;
  app.add_option("--points", points, "Points in each generated binary file (ASCII PLY: a tenth)")
      ->check(CLI::Range(uint64_t(1000), uint64_t(1) << 32))
      ->capture_default_str();
  app.add_option("--out", out, "Results folder; inputs are generated (and kept) in OUT/inputs")
      ->capture_default_str();
  app.add_option("--repeat", repeat, "Measurements per input; the best is kept")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--build-points", build_points,
                 "Also build a store from a LAS file and from its LAZ twin of this many points "
                 "(0: skip)")
      ->check(CLI::Range(uint64_t(0), uint64_t(1) << 32))
      ->capture_default_str();
  app.add_flag("--remove-inputs", remove_inputs, "Delete OUT/inputs when done");
  app.add_flag("--quiet", quiet, "No progress output on stderr");
  CLI11_PARSE(app, argc, argv);

  try {
    const fs::path out_dir = fs::absolute(out);
    std::vector<Input> inputs = prepareInputs(out_dir / "inputs", points, quiet);
    std::vector<uint8_t> buffer(kPlainReadBuffer);
    std::vector<Result> results;
    {
      tessera::Progress progress("reader_throughput", inputs.size() * size_t(repeat) * 2,
                                 "measurements", quiet);
      for (const Input& in : inputs) results.push_back(measure(in, repeat, buffer, progress));
    }
    const std::string header =
        "format,file,points,bytes,plain_read_s,reader_s,plain_mpts_per_s,reader_mpts_per_s,"
        "reader_mb_per_s,ratio";
    std::ofstream csv(out_dir / kCsvName);
    std::cout << header << "\n";
    csv << header << "\n";
    for (const Result& r : results) {
      std::cout << csvLine(r) << "\n";
      csv << csvLine(r) << "\n";
    }
    csv.close();
    if (!csv) throw std::runtime_error("cannot write " + (out_dir / kCsvName).string());
    drawChart(out_dir, results.size(), points, repeat, quiet);
    if (build_points > 0) measureBuilds(out_dir, build_points, repeat, quiet);
    if (remove_inputs) fs::remove_all(out_dir / "inputs");
  } catch (const std::exception& e) {
    std::cerr << "reader_throughput: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
