// tessera-render: renders a plain view, one tile of a wall, the wall mosaic (bezels drawn dark)
// or the wall's whole extent to PNG, headless; posters larger than one render (poster.h), both
// eyes of a stereo view (stereo.h) and camera paths as movies or PNG sequences (path_frames.h,
// media/movie_writer.h). `tessera-render --help` lists the options.
#include <CLI/CLI.hpp>

#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <set>
#include <span>

#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <sstream>

#include <tessera/core/cli.h>
#include <tessera/core/file_checks.h>
#include <tessera/core/progress.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/scan_preview.h>
#include <tessera/lod/store_builder.h>
#include <tessera/lod/store_cache.h>
#include <tessera/media/movie_writer.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/inset.h>
#include <tessera/render/pass_timing.h>
#include <tessera/render/path_frames.h>
#include <tessera/render/poster.h>
#include <tessera/render/projector_pass.h>
#include <tessera/render/scene_draw_list.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/render/stereo.h>
#include <tessera/render/view_renderer.h>
#include <tessera/render/wall_mosaic.h>
#include <tessera/render/window.h>
#include <tessera/sync/camera_path.h>
#include <tessera/sync/config.h>
#include <tessera/sync/vec3.h>
#include <tessera/sync/view.h>
#include <tessera/sync/viewer_head.h>

namespace {

using namespace tessera;
namespace fs = std::filesystem;
using sync::vec;

/// A bad command line: main() reports it and exits 2 (cli::runMain).
[[noreturn]] void usage(const std::string& what) {
  throw cli::UsageError(what);
}

/// `eye=X,Y,Z;target=X,Y,Z;up=X,Y,Z`
config::Camera parseCamera(const std::string& s) {
  config::Camera c;
  size_t seen = 0;
  std::stringstream in(s);
  for (std::string part; std::getline(in, part, ';');) {
    auto eq = part.find('=');
    if (eq == std::string::npos) usage("--camera: expected eye=X,Y,Z;target=X,Y,Z;up=X,Y,Z");
    std::string key = part.substr(0, eq);
    glm::dvec3 v = cli::parseVec3(part.substr(eq + 1), "--camera " + key);
    config::Vec3* dst = key == "eye"      ? c.mutable_eye()
                        : key == "target" ? c.mutable_target()
                        : key == "up"     ? c.mutable_up()
                                          : nullptr;
    if (!dst) usage("--camera: unknown key '" + key + "' (eye, target, up)");
    dst->set_x(v.x);
    dst->set_y(v.y);
    dst->set_z(v.z);
    ++seen;
  }
  if (seen != 3) usage("--camera: give eye, target and up");
  sync::requireView(sync::vec(c.eye()), sync::vec(c.target()), sync::vec(c.up()), "--camera");
  return c;
}

/// --head 'eye=X,Y,Z;right=X,Y,Z;separation=S' (right: +x when absent; separation: each slot's
/// own when absent): the viewer's head in the wall frame, metres. Checked against the wall by
/// the caller (sync::headProblem()).
scene::Head parseHead(const std::string& s) {
  scene::Head h;
  sync::set(h.mutable_right(), glm::dvec3(1.0, 0.0, 0.0));
  std::stringstream in(s);
  for (std::string part; std::getline(in, part, ';');) {
    const auto eq = part.find('=');
    if (eq == std::string::npos)
      usage("--head: expected eye=X,Y,Z[;right=X,Y,Z][;separation=S] (metres, wall frame)");
    const std::string key = part.substr(0, eq), value = part.substr(eq + 1);
    if (key == "eye") {
      sync::set(h.mutable_eye(), cli::parseVec3(value, "--head eye"));
    } else if (key == "right") {
      sync::set(h.mutable_right(), cli::parseVec3(value, "--head right"));
    } else if (key == "separation") {
      char* end = nullptr;
      h.set_eye_separation(std::strtod(value.c_str(), &end));
      if (value.empty() || *end != '\0') usage("--head separation: '" + value + "' is not a number");
    } else {
      usage("--head: unknown key '" + key + "' (eye, right, separation)");
    }
  }
  if (!h.has_eye()) usage("--head: give at least eye=X,Y,Z");
  return h;
}

/// A --model file that can be stat'ed, else a bad command line naming it.
void requireFile(const fs::path& input) {
  std::error_code ec;
  (void)fs::file_size(input, ec);
  if (ec) usage("--model " + input.string() + ": " + ec.message());
}

/// A .tlod as it is; any other readable file is converted once into a cache folder
/// (lod/store_cache.h). Read and build errors propagate to main's handler.
fs::path storeFor(const fs::path& input) {
  if (input.extension() == ".tlod" || input.extension() == ".tmesh") return input;
  requireFile(input);
  return lod::cachedStoreFor(input, "tessera-render");
}

/// The camera fitted to a world box (lo, hi).
config::Camera fitCamera(const glm::dvec3& lo, const glm::dvec3& hi) {
  const glm::dvec3 c = 0.5 * (lo + hi);
  glm::dvec3 ext = hi - lo;
  double r = 0.5 * glm::length(ext);
  // Flat data (terrain, LiDAR) seen from the south and above with z up; objects from the front.
  bool flat = ext.z < 0.3 * std::max(ext.x, ext.y);
  glm::dvec3 eye = flat ? c + glm::dvec3(0, -1.6 * r, 1.2 * r) : c + glm::dvec3(0, 0, 2.6 * r);
  glm::dvec3 up = flat ? glm::dvec3(0, 0, 1) : glm::dvec3(0, 1, 0);
  config::Camera cam;
  sync::set(cam.mutable_eye(), eye);
  sync::set(cam.mutable_target(), c);
  sync::set(cam.mutable_up(), up);
  return cam;
}

config::Camera fitCamera(const render::ModelInstance& m) {
  const auto [lo, hi] = render::worldBounds(m);
  return fitCamera(lo, hi);
}

/// A raw scan drawn from its preview store (lod/scan_preview.h) until its whole store is built:
/// the store and the instance that draw it.
struct PreviewedModel {
  std::unique_ptr<lod::ScanPreview> preview;
  size_t store = 0, instance = 0;
};

/// Shows the view in `win` until it closes (or `frames` frames): left drag orbits the target,
/// right drag pans, the wheel zooms. Frames never wait for data; it streams in behind them.
/// Returns the camera the user left.
config::Camera interactive(render::Window& win, config::Camera cam,
                           const std::function<render::ViewSetup(const config::Camera&)>& viewOf,
                           std::span<const render::ModelInstance> instances,
                           const render::RenderOptions& options,
                           const render::StreamerOptions& stream_options,
                           const render::Overlay* overlay, int frames,
                           const std::function<void(render::ViewRenderer&)>& before_frame = {}) {
  const render::ViewSetup first = viewOf(cam);
  render::ViewRenderer r(first.width, first.height, nullptr, stream_options);
  for (int frame = 1; !win.closing() && (frames == 0 || frame <= frames); ++frame) {
    if (before_frame) before_frame(r);
    render::RenderStats st;
    r.draw(instances, viewOf(cam), options, &st, overlay);
    win.present(r.imageBuffer(), first.width, first.height);
    char title[160];
    std::snprintf(title, sizeof title, "tessera-render: %llu points, %.0f ms, %zu chunks loading",
                  (unsigned long long)st.points, st.totalMs(), size_t(st.stream.queued));
    win.setTitle(title);
    const render::WindowInput in = win.poll();
    glm::dvec3 eye = vec(cam.eye()), target = vec(cam.target()), up = glm::normalize(vec(cam.up()));
    glm::dvec3 back = eye - target;
    const double dist = glm::length(back);
    const glm::dvec3 right = glm::normalize(glm::cross(-back, up));
    if (in.left && glm::length(in.cursor_delta) > 0) {
      // Turntable: yaw about the up axis, pitch about the view's right axis.
      const double yaw = -in.cursor_delta.x * 0.008, pitch = -in.cursor_delta.y * 0.008;
      back = glm::dvec3(glm::rotate(glm::dmat4(1.0), yaw, up) *
                        glm::rotate(glm::dmat4(1.0), pitch, right) * glm::dvec4(back, 0.0));
    }
    if (in.right && glm::length(in.cursor_delta) > 0) {
      const double per_px = 2.0 * dist * std::tan(glm::radians(22.5)) / double(in.size.y + 1);
      const glm::dvec3 cam_up = glm::normalize(glm::cross(right, -back));
      target += (-in.cursor_delta.x * right + in.cursor_delta.y * cam_up) * per_px;
    }
    if (in.scroll != 0) back *= std::pow(0.85, in.scroll);
    sync::set(cam.mutable_eye(), target + back);
    sync::set(cam.mutable_target(), target);
  }
  return cam;
}

/// Renders every frame of `path` at `fps` with `picture` into the movie `movie` and/or the PNG
/// sequence in `frames_dir` (whichever is not empty), with a progress bar; `start` runs first.
int writePathFrames(const config::CameraPath& path, double fps, const std::string& movie,
                    const std::string& frames_dir,
                    const std::function<render::Image(const config::Camera&)>& picture,
                    const std::function<void()>& start, const std::function<void()>& warn) {
  const size_t n = render::pathFrameCount(path, fps);
  if (!frames_dir.empty()) {
    std::error_code ec;
    fs::create_directories(frames_dir, ec);
    if (ec || !fs::is_directory(frames_dir))
      usage("--frames-dir " + frames_dir + ": not a folder that can be made" +
            (ec ? ": " + ec.message() : ""));
  }
  start();
  std::unique_ptr<media::MovieWriter> writer;
  Progress progress(movie.empty() ? frames_dir : movie, n, " frames");
  render::forEachPathFrame(path, fps, [&](size_t i, double, const config::Camera& c) {
    const render::Image img = picture(c);
    if (!movie.empty()) {
      if (!writer) {
        media::MovieSettings ms;
        ms.width = int(img.width);
        ms.height = int(img.height);
        ms.fps = fps;
        writer = std::make_unique<media::MovieWriter>(movie, ms);
      }
      writer->write(img.rgba, int(img.width), int(img.height));
    }
    if (!frames_dir.empty()) render::writePng(render::framePngPath(frames_dir, i).string(), img);
    progress.update(i + 1);
  });
  progress.finish();
  warn();
  if (writer) {
    writer->finish();
    std::printf("wrote %s (%zu frames at %g fps, %s)\n", movie.c_str(), n, fps,
                writer->encoder().c_str());
  }
  if (!frames_dir.empty())
    std::printf("wrote %s/frame-000000.png .. %s\n", frames_dir.c_str(),
                render::framePngPath(frames_dir, n - 1).filename().c_str());
  return 0;
}

int run(int argc, char** argv) {
  CLI::App app{
      "tessera-render: render point stores headless to PNG: a view, a wall tile, the mosaic or the "
      "whole wall"};
  std::string wall_path, tile_name, size = "1280x720", scene_path, camera, background, stats_path,
                                    out;
  std::vector<std::string> models;
  bool mosaic = false, whole = false, edl = false, edl_classic = false, window = false;
  int frames = 0;
  double fovy = 45.0, lod_px = 0.0, splat_scale = 2.0, budget_mb = 1024.0;
  app.add_option("--wall", wall_path, "Wall configuration (JSON)");
  auto* tile_opt = app.add_option("--tile", tile_name, "Render this tile of the wall");
  auto* mosaic_opt =
      app.add_flag("--mosaic", mosaic,
                   "Render every tile and assemble the wall, bezels dark; with projectors (blend, "
                   "warp, MPCDI) each tile through its projector's pass as its node shows it, "
                   "the screen recomposed from them, and OUT-projectors.png their pictures");
  auto* whole_opt =
      app.add_flag("--whole", whole, "Render the wall's whole extent as one image (seam check)");
  tile_opt->excludes(mosaic_opt)->excludes(whole_opt);
  mosaic_opt->excludes(whole_opt);
  std::vector<std::string> inset_args;
  app.add_option(
         "--inset", inset_args,
         "Place a foveal inset of the wall: NAME=X,Y, its centre on the wall plane "
         "(metres), over the scene's settings.inset; --mosaic also writes OUT-inset-NAME.png")
      ->take_all();
  std::string head_arg;
  app.add_option("--head", head_arg,
                 "The viewer's head on the wall over the scene's settings.head: "
                 "'eye=X,Y,Z;right=X,Y,Z;separation=S' (wall frame, metres; right +x and each "
                 "stereo slot's own separation when absent): every tile's frustum and stereo eye "
                 "are seen from it");
  app.add_option("--size", size, "Plain view size WxH (without --wall)")->capture_default_str();
  app.add_option("--fovy", fovy, "Plain view vertical field of view, degrees")
      ->check(cli::finiteRange(1.0, 170.0))
      ->capture_default_str();
  app.add_option("--scene", scene_path,
                 "Scene configuration (JSON): models, camera, background, lod");
  app.add_option("--model", models,
                 "A .tlod store or any readable scan (converted once into ~/.cache/tessera)");
  app.add_option("--camera", camera,
                 "eye=X,Y,Z;target=X,Y,Z;up=X,Y,Z (default: the scene's, else fitted)");
  app.add_option("--lod-px", lod_px, "LOD threshold in pixels (default: the scene's, else 1)")
      ->check(cli::positiveFinite(1e6));
  uint64_t point_budget = 0;
  double budget_per_pixel = render::RenderOptions{}.budget_per_covered_pixel;
  bool no_coverage_stop = false;
  auto* budget_opt =
      app.add_option("--point-budget", point_budget,
                     "Most points per model and picture (a wall's tiles share the wall's), "
                     "refined largest screen error first (by default --points-per-pixel sets "
                     "it; 0: no budget at all, every level the pixels ask for)")
          ->check(cli::anyInteger<uint64_t>());
  app.add_option("--points-per-pixel", budget_per_pixel,
                 "Without --point-budget: a budget of this many points per pixel the model "
                 "covers, never below --budget-floor (0: none; the default 2 draws about a "
                 "point a pixel shown: fast on large scans seen whole, coarser colour there)")
      ->check(cli::finiteRange(0.0, 1e6))
      ->capture_default_str();
  uint64_t budget_floor = render::RenderOptions{}.budget_floor;
  app.add_option("--budget-floor", budget_floor,
                 "The --points-per-pixel budget is at least this many points per model: "
                 "smaller cuts keep every level their pixels ask for")
      ->check(cli::anyInteger<uint64_t>())
      ->capture_default_str();
  app.add_flag("--no-coverage-stop", no_coverage_stop,
               "Refine also where nearer points already cover the pixels (a volume of points "
               "then draws every leaf; by default only its front)");
  app.add_option("--background", background, "R,G,B in [0, 1]");
  app.add_flag("--edl", edl,
               "Eye-dome lighting (shape without normals; default: the scene's shading)");
  app.add_flag("--edl-classic", edl_classic,
               "Eye-dome lighting from raw depths, the classic method (speckles on noisy scans)");
  int relative_depth = 0;
  double contour_interval = 0.0, contour_phase = 0.0;
  std::string contour_axis;
  app.add_option("--relative-depth", relative_depth,
                 "Relative depth (the view depth minus its Gaussian blur of this half-width in "
                 "pixels: the fine relief, in the viridis colour map over the frame's range; "
                 "the tiles of --mosaic agree on one range)")
      ->check(cli::integerRange(1, render::kMaxRelativeDepthRadius));
  float relative_depth_m = 0.0f;
  app.add_option("--relative-depth-m", relative_depth_m,
                 "Relative depth with its blur's half-width in units (metres) on the model, at "
                 "the camera's distance to its target")
      ->check(cli::positiveFinite(1e12));
  app.add_option("--contours", contour_interval,
                 "Contour lines every this many units (metres) of view depth, one pixel wide")
      ->check(cli::positiveFinite(1e12));
  app.add_option("--contour-axis", contour_axis,
                 "X,Y,Z: contour lines of the height along this world axis instead of the depth "
                 "(0,0,1: a LiDAR scan's vertical)");
  app.add_option("--contour-phase", contour_phase, "Units: lines at PHASE + k * interval")
      ->check(cli::finiteRange(-1e12, 1e12));
  float ao = 0.0f, ao_radius = 0.0f, ao_radius_px = 0.0f;
  bool ao_full = false;
  app.add_option("--ao", ao,
                 "Screen-space ambient occlusion of this strength (1: the usual), over the "
                 "colours and eye-dome lighting; settled pictures average its frames")
      ->check(cli::finiteRange(0.0, 4.0));
  app.add_option("--ao-radius", ao_radius, "Its radius in units (metres) on the model")
      ->check(cli::positiveFinite(1e12));
  app.add_option("--ao-radius-px", ao_radius_px, "Its radius in pixels at any depth (default 32)")
      ->check(cli::finiteRange(1.0, render::kAoMaxRadiusPx));
  std::string stored_ao;
  app.add_option("--stored-ao", stored_ao,
                 "Points of stores carrying ambient occlusion (tessera-lod ao): modulate (their "
                 "colour times it, the default), off, or alone (the AO as grey)")
      ->check(CLI::IsMember({"modulate", "off", "alone"}));
  bool ao_grid = false;
  app.add_flag("--ao-grid", ao_grid,
               "Gather ambient occlusion over the frames drawn into a multi-view grid and shade "
               "from it (with a window: as the view moves)");
  app.add_flag("--ao-full-resolution", ao_full,
               "Ambient occlusion on every pixel (default: on a quarter, upsampled by depth)");
  app.add_option("--splat-scale", splat_scale,
                 "Splat size as a multiple of the projected sample spacing (raise for LiDAR)")
      ->check(cli::finiteRange(0.25, 8.0))
      ->capture_default_str();
  std::string fill = "auto";
  app.add_option("--fill", fill,
                 "How opaque points close surfaces: auto (whichever of the two below costs the "
                 "frame less; discs on a wall's tiles), discs (each point a disc of its splat "
                 "size), pullpush (1 px points, then a screen-space pull-push fill reaching as "
                 "far as the discs would: cost by pixels, not splat area), or none (1 px points, "
                 "open: the cost floor)")
      ->check(CLI::IsMember({"auto", "discs", "pullpush", "none"}))
      ->capture_default_str();
  app.add_option("--gpu-budget-mb", budget_mb, "GPU bytes for resident chunks, MiB")
      ->check(cli::finiteRange(1.0, 1e6))
      ->capture_default_str();
  uint32_t loader_threads = 0;
  app.add_option("--loader-threads", loader_threads, "Threads decoding chunks (0: one a core)")
      ->check(cli::integerRange<uint32_t>(0, 256))
      ->capture_default_str();
  uint32_t spbr_l = 0, spbr_progressive = 0;
  double spbr_max_k = 1e9;
  bool no_slant = false, blend_colors = false;
  std::string spbr_copies = "cell";
  app.add_option("--spbr-L", spbr_l,
                 "See-through: ensembles per frame for models with opacity < 1 (default: the "
                 "scene's, else 16)")
      ->check(cli::integerRange<uint32_t>(1, 4096));
  app.add_option("--spbr-progressive", spbr_progressive,
                 "See-through: keep adding ensembles up to this many while the view rests")
      ->check(cli::integerRange<uint32_t>(0, 65536));
  app.add_option("--spbr-max-k", spbr_max_k,
                 "See-through: most copies of a point over the ensembles (default: as the "
                 "paper, up to L; 1: independent ensembles with larger discs, blurred)")
      ->check(cli::finiteRange(0.01, 1e9));
  bool flat_shading = false;
  app.add_flag("--flat", flat_shading,
               "Meshes: light each triangle with its own facet normal (shows the triangulation)");
  app.add_flag("--blend-colors", blend_colors,
               "Colour points: blend the colours of the points within a splat's depth of the "
               "nearest on each pixel (smooth, alias-free colour; as Potree's high-quality "
               "splatting)");
  app.add_option("--spbr-copies", spbr_copies,
                 "See-through: where a point's copies go. cell (default): stratified over the "
                 "point's surface cell (binomial noise on sparse scans, sharp edges; 16 GPU bytes "
                 "a point and loader time); paper: where the point is (binary noise on sparse "
                 "scans); gaussian: jittered 1.5 node spacings over surface cells (blurs edges)")
      ->check(CLI::IsMember({"cell", "paper", "gaussian"}))
      ->capture_default_str();
  app.add_flag("--no-slant-shading", no_slant,
               "See-through: cross-sections s cos(theta), no opacity gain on slanted surfaces");
  app.add_option("--stats", stats_path, "Append per-view statistics as CSV");
  app.add_flag("--window", window,
               "Show the plain view in a window (GLFW): left drag orbits, right drag pans, wheel "
               "zooms, Esc quits; -o then saves the last view");
  app.add_option("--frames", frames, "With --window: quit after this many frames (0: on close)")
      ->check(cli::integerRange(0, 1 << 30));
  std::string poster, stereo, path_file, movie, frames_dir;
  uint32_t poster_part = render::kDefaultPosterPart;
  double poster_memory_mb = 1024.0, eye_separation = 0.065, fps = 30.0;
  app.add_option("--poster", poster,
                 "Render the view (with --wall: the whole wall's view) as a WxH poster, up to " +
                     std::to_string(render::kMaxPosterSide) +
                     " pixels a side: in parts with the view's own off-axis frustum, each with "
                     "the guard band its screen passes reach (eye-dome lighting, ambient "
                     "occlusion, relative depth and contours show no seams), the PNG written a "
                     "row of parts at a time, a progress bar on stderr");
  app.add_option("--poster-part", poster_part, "Poster: the largest part, pixels a side")
      ->check(cli::integerRange<uint32_t>(16, render::kMaxPosterPart))
      ->capture_default_str();
  app.add_option("--poster-memory-mb", poster_memory_mb,
                 "Poster: memory for one row of parts and one part's render, MiB (rows of parts "
                 "get shorter to fit)")
      ->check(cli::finiteRange(1.0, 1e7))
      ->capture_default_str();
  app.add_option("--stereo", stereo,
                 "Both eyes, off-axis through the screen (the wall plane; for a plain view the "
                 "plane through the camera's target), which shows at zero parallax: sbs (side "
                 "by side, left eye left), tb (left eye on top), anaglyph (red-cyan: red from "
                 "the left eye) or pair (OUT-left.png and OUT-right.png; the only one with "
                 "--poster)")
      ->check(CLI::IsMember({"sbs", "tb", "anaglyph", "pair"}));
  app.add_option("--eye-separation", eye_separation, "Stereo: metres between the eyes")
      ->check(cli::positiveFinite(10.0))
      ->capture_default_str();
  app.add_option("--path", path_file,
                 "Camera path (JSON, configs/paths/) to render with --movie or --frames-dir: "
                 "frame i shows the camera at i / fps seconds, each frame settled; the path's "
                 "keyframes move the camera, its actions are not applied");
  const std::string encoder = media::movieEncoderName();
  app.add_option(
      "--movie", movie,
      "Write the path as an MP4 movie (this build encodes with " +
          (encoder.empty() ? std::string("nothing: no H.264, HEVC or MPEG-4 encoder") : encoder) +
          "; libx264 at CRF 18 where present, else H.264, HEVC or MPEG-4 part 2); "
          "its sides must be even");
  app.add_option("--frames-dir", frames_dir,
                 "Write the path's frames as PNGs DIR/frame-000000.png, ... (made if missing)");
  app.add_option("--fps", fps, "Frames a second of --movie and --frames-dir")
      ->check(cli::positiveFinite(240.0))
      ->capture_default_str();
  std::string preview_out;
  uint64_t preview_points = lod::SampleOptions{}.points;
  app.add_option("--preview", preview_out,
                 "Raw scans whose store is not cached yet: first write this PNG, drawn from an "
                 "even sample of each scan read without parsing the whole file (LAS, LAZ, binary "
                 "PLY; other formats say so and wait for the build) with the final picture's "
                 "camera, then build the store and write -o; the window shows the preview "
                 "while the store builds without it");
  app.add_option("--preview-points", preview_points, "Points in a scan's preview sample")
      ->check(cli::integerRange<uint64_t>(1000, 100'000'000))
      ->capture_default_str();
  auto* out_opt = app.add_option(
      "-o,--output", out,
      "Output PNG (required without --window, --movie or --frames-dir; with --stereo pair the "
      "files OUT-left.png and OUT-right.png)");
  if (const auto code = cli::parse(app, argc, argv, "tessera-render")) return *code;
  const bool path_run = !path_file.empty();
  if (path_run != (!movie.empty() || !frames_dir.empty()))
    usage(path_run ? "--path needs --movie OUT.mp4 or --frames-dir DIR"
                   : "--movie and --frames-dir render a camera path: give --path PATH.json");
  if (path_run && (window || !poster.empty() || !out.empty()))
    usage("--path renders a movie or frames: drop --window, --poster and -o");
  if (out.empty() && !window && !path_run) usage("-o OUT.png is required (or --window)");
  if (!poster.empty() && (window || !tile_name.empty() || mosaic || !stats_path.empty()))
    usage(
        "--poster renders the plain view or the whole wall: drop --window, --tile, --mosaic "
        "and --stats");
  if (!stereo.empty() && window) usage("--stereo writes files: drop --window");
  if (stereo == "pair" && path_run)
    usage("--stereo pair writes two pictures: a movie or frames take sbs, tb or anaglyph");
  if (!poster.empty() && !stereo.empty() && stereo != "pair")
    usage("--poster --stereo " + stereo + ": posters take --stereo pair (two files)");
  const cli::Size poster_size =
      poster.empty() ? cli::Size{} : cli::parseSize(poster, "--poster", render::kMaxPosterSide);
  // How the poster is cut, before anything loads: too little memory is a bad command line.
  render::PosterPlan plan;
  if (!poster.empty()) {
    try {
      plan = render::planPoster(poster_size.width, poster_size.height, poster_part,
                                uint64_t(poster_memory_mb * 1048576.0));
    } catch (const render::RenderError& e) {
      usage(std::string("--poster-memory-mb: ") + e.what());
    }
  }
  if (window && !wall_path.empty()) usage("--window shows a plain view: drop --wall");
  if (!preview_out.empty() && (path_run || !poster.empty() || stereo == "pair" || window))
    usage(
        "--preview writes one picture before -o: drop --path, --poster, --stereo pair and "
        "--window (the window shows the preview by itself)");
  (void)out_opt;
  // Every value is checked before any file is opened: a bad one never costs a load.
  const cli::Size plain_size = cli::parseSize(size, "--size", 16384);
  // A movie's frames (both eyes side by side or on top of each other) have even sides.
  if (!movie.empty() && wall_path.empty() &&
      ((plain_size.width * (stereo == "sbs" ? 2 : 1)) % 2 != 0 ||
       (plain_size.height * (stereo == "tb" ? 2 : 1)) % 2 != 0))
    usage("--size " + size + ": a movie's frames need even sides");
  const std::optional<config::Camera> camera_given =
      camera.empty() ? std::nullopt : std::optional(parseCamera(camera));
  const glm::dvec3 background_rgb =
      background.empty() ? glm::dvec3(0.0) : cli::parseVec3(background, "--background", 0.0, 1.0);

  try {
    // A bad path file is refused before any store is opened.
    const config::CameraPath camera_path =
        path_run ? sync::loadCameraPath(path_file) : config::CameraPath{};
    std::vector<std::unique_ptr<lod::PointStore>> stores;
    std::vector<std::unique_ptr<lod::MeshStore>> mesh_stores;
    std::vector<render::ModelInstance> instances;
    std::vector<PreviewedModel> previewed;  // raw scans drawn from their previews for now
    render::RenderOptions options;
    config::Camera cam;
    bool have_camera = false;
    // A scene goes the way it goes on the wall: a scene graph, and the draw list that render
    // nodes and the console use (render/scene_draw_list.h), so all draw it alike.
    sync::SceneGraph graph;
    render::SceneDrawList scene_list;
    render::Overlay scene_overlay;  // the scene's sketches, avatars and annotations
    if (!scene_path.empty()) {
      graph = render::loadSceneWithStores(scene_path, "tessera-render");
      const auto& listed = scene_list.update(graph, sync::SceneChanges::all());
      instances.assign(listed.begin(), listed.end());
      cam = graph.camera();
      have_camera = true;
      options = render::SceneDrawList::options(graph, float(splat_scale));
      options.highlights = render::sceneHighlights(graph);
      render::appendSceneOverlay(graph, scene_overlay);
    }
    for (const std::string& m : models) {
      // FILE or FILE:OPACITY (a colon followed by a number, so paths with colons still work).
      std::string file = m;
      float opacity = 1.0f;
      const auto colon = m.rfind(':');
      if (colon != std::string::npos && colon > 0 && m.find('/', colon) == std::string::npos) {
        char* end = nullptr;
        const std::string tail = m.substr(colon + 1);
        const double v = std::strtod(tail.c_str(), &end);
        if (end == tail.c_str() || *end != '\0' || !(v > 0.0 && v <= 1.0))
          usage("--model " + m + ": opacity after ':' must be a number in (0, 1]");
        file = m.substr(0, colon);
        opacity = float(v);
      }
      if (render::SceneDrawList::isMeshPath(file) && opacity < 1.0f) {
        // A see-through mesh: points on its triangles (lod/mesh_samples.h), cached.
        stores.push_back(lod::PointStore::open(lod::cachedStoreFor(file, "tessera-render")));
        instances.push_back({stores.back().get(), render::storeModel(*stores.back()), opacity});
        continue;
      }
      if (render::SceneDrawList::isMeshPath(file)) {
        mesh_stores.push_back(lod::MeshStore::open(file));
        instances.push_back({nullptr, render::storeModel(*mesh_stores.back()), opacity,
                             glm::u8vec3(0), mesh_stores.back().get()});
        continue;
      }
      if ((!preview_out.empty() || window) && fs::path(file).extension() != ".tlod") {
        // A raw scan: its preview store first, its whole store once built.
        requireFile(file);
        auto preview = std::make_unique<lod::ScanPreview>(file, "tessera-render",
                                                          lod::SampleOptions{preview_points});
        if (preview->hasPreview()) {
          std::fprintf(stderr,
                       "tessera-render: %s: preview of %llu points (sampled in %.2f s, built in "
                       "%.2f s); the whole store follows\n",
                       file.c_str(), (unsigned long long)preview->previewPoints(),
                       preview->sampleSeconds(), preview->previewBuildSeconds());
          stores.push_back(lod::PointStore::open(preview->previewPath()));
          previewed.push_back({std::move(preview), stores.size() - 1, instances.size()});
        } else {
          if (!preview->whyNot().empty())
            std::fprintf(stderr,
                         "tessera-render: %s cannot be sampled (%s): the first picture waits "
                         "for its whole store\n",
                         file.c_str(), preview->whyNot().c_str());
          stores.push_back(lod::PointStore::open(preview->finalStore()));
        }
      } else {
        stores.push_back(lod::PointStore::open(storeFor(file)));
      }
      instances.push_back({stores.back().get(), render::storeModel(*stores.back()), opacity});
    }
    if (instances.empty())
      usage(scene_path.empty()
                ? "nothing to render: give --scene or --model"
                : "nothing to render: every model of " + scene_path + " is hidden or at opacity 0");
    if (camera_given) {
      cam = *camera_given;
      have_camera = true;
    }
    if (!have_camera) cam = fitCamera(instances.front());
    // A previewed scan's camera is fitted to its header's bounds, which the whole store shares,
    // so the preview and the final picture are seen from one camera.
    if (!have_camera && !previewed.empty() && previewed.front().instance == 0 &&
        previewed.front().preview->headerBounds())
      cam = fitCamera(previewed.front().preview->headerBounds()->first,
                      previewed.front().preview->headerBounds()->second);
    if (lod_px > 0) options.lod_pixels = lod_px;
    if (edl) options.edl.strength = 1.0f;
    if (edl_classic) options.edl = render::EdlOptions::classic();
    if (relative_depth > 0) {
      options.relative_depth.enabled = true;
      options.relative_depth.radius = relative_depth;
    }
    if (relative_depth_m > 0.0f) {
      options.relative_depth.enabled = true;
      options.relative_depth.radius_m = relative_depth_m;
      options.relative_depth.radius_depth =
          std::max(1e-9, glm::length(sync::vec(cam.target()) - sync::vec(cam.eye())));
    }
    if (stored_ao == "off") options.stored_ao = render::StoredAo::kOff;
    if (stored_ao == "alone") options.stored_ao = render::StoredAo::kAlone;
    if ((ao_radius > 0.0f || ao_radius_px > 0.0f || ao_full || ao_grid) && !(ao > 0.0f))
      usage("--ao-radius, --ao-radius-px, --ao-full-resolution and --ao-grid need --ao STRENGTH");
    options.ao_grid.enabled = ao_grid;
    if (ao > 0.0f) {
      options.ao.enabled = true;
      options.ao.strength = ao;
      options.ao.radius = ao_radius;
      if (ao_radius_px > 0.0f) options.ao.radius_px = ao_radius_px;
      options.ao.half_resolution = !ao_full;
    }
    if (!contour_axis.empty() && !(contour_interval > 0))
      usage("--contour-axis needs --contours INTERVAL");
    if (contour_interval > 0) {
      options.contours.enabled = true;
      options.contours.interval = contour_interval;
      options.contours.phase = contour_phase;
      if (!contour_axis.empty()) {
        options.contours.height = true;
        options.contours.axis = cli::parseVec3(contour_axis, "--contour-axis");
        if (glm::length(options.contours.axis) == 0.0) usage("--contour-axis: a zero vector");
      }
    }
    options.splat_scale = float(splat_scale);
    options.point_budget = point_budget;
    options.budget_per_covered_pixel = budget_opt->count() > 0 && point_budget == 0
                                           ? 0.0  // --point-budget 0: none
                                           : budget_per_pixel;
    options.budget_floor = budget_floor;
    options.coverage_stop = !no_coverage_stop;
    if (spbr_l > 0) options.spbr.ensembles = spbr_l;
    options.spbr.progressive_max = spbr_progressive;
    options.spbr.max_k = spbr_max_k;
    options.spbr.slant_shading = !no_slant;
    if (spbr_copies == "paper") options.spbr = render::SpbrOptions::papersCopies(options.spbr);
    if (spbr_copies == "gaussian") options.spbr = render::SpbrOptions::gaussianJitter(options.spbr);
    options.blend_colors = blend_colors;
    options.flat_shading = flat_shading;
    options.fill = fill == "pullpush" ? render::SurfaceFill::kPullPush
                   : fill == "none"   ? render::SurfaceFill::kNone
                   : fill == "discs"  ? render::SurfaceFill::kDiscs
                                      : render::SurfaceFill::kAuto;
    if (!background.empty()) options.background = glm::vec3(background_rgb);

    // What this run reads must never be what it writes (-o, --stats), by any path.
    std::vector<fs::path> read;
    for (const std::string& p : {scene_path, wall_path}) {
      if (!p.empty()) read.push_back(p);
    }
    for (const auto& m : instances) read.push_back(m.hierarchy()->path());
    for (const std::string& m : models) read.push_back(m.substr(0, m.rfind(':')));
    for (const std::string& m : models) read.push_back(m);
    if (!path_file.empty()) read.push_back(path_file);
    if (!out.empty()) cli::refuseOverwrite(out, read, "-o");
    if (!preview_out.empty()) cli::refuseOverwrite(preview_out, read, "--preview");
    if (!movie.empty()) cli::refuseOverwrite(movie, read, "--movie");
    if (!stats_path.empty()) {
      cli::refuseOverwrite(stats_path, read, "--stats");
      render::timePasses(true);  // the CSV's per-pass columns
    }
    std::error_code ec;
    if (!out.empty() && !stats_path.empty() &&
        fs::weakly_canonical(out, ec) == fs::weakly_canonical(stats_path, ec))
      usage("-o " + out + " and --stats " + stats_path + " are the same file");

    std::unique_ptr<render::GlContext> ctx;
    std::unique_ptr<render::Window> win;
    if (window) {
      try {
        win = render::Window::open(std::clamp(plain_size.width, 64u, 4096u),
                                   std::clamp(plain_size.height, 64u, 4096u), "tessera-render");
      } catch (const render::RenderError& e) {
        std::fprintf(stderr, "tessera-render: %s; rendering headless\n", e.what());
        window = false;
        if (out.empty()) usage("no window and no -o: nothing to do");
      }
    }
    if (!win) ctx = render::GlContext::createHeadless();
    std::ofstream stats_file;
    if (!stats_path.empty()) {
      bool fresh = !fs::exists(stats_path);
      stats_file.open(stats_path, std::ios::app);
      if (!stats_file)
        usage("--stats " + stats_path + ": cannot write: " + whyNotWritable(stats_path, errno));
      if (fresh) {
        stats_file << "view,width,height,frames,cut_nodes,nodes,points,corrupt_chunks,"
                      "resident_chunks,resident_bytes,store_bytes,select_ms,upload_ms,depth_ms,"
                      "color_ms,resolve_ms,readback_ms,frame_ms,ensembles,copies\n";
      }
    }
    uint64_t store_bytes = 0;
    store_bytes += scene_list.storeBytes();
    for (const auto& s : stores) store_bytes += s->summary().file_bytes;
    for (const auto& s : mesh_stores) store_bytes += s->summary().file_bytes;
    // Each view streams on its own, as the wall node driving that tile would.
    render::StreamerOptions stream_options;
    stream_options.budget_bytes = uint64_t(budget_mb * 1048576.0);
    stream_options.loader_threads = loader_threads;
    stream_options.normals = no_slant;  // cos(theta) needs a normal per point
    for (const auto& m : instances) stream_options.density_ratios |= m.opacity < 1.0f;
    // Surface cells only where copies move over them (SpbrOptions::copies).
    stream_options.surface_cells =
        stream_options.density_ratios && options.spbr.copies != render::SpbrCopies::kAtPoint;
    const render::Overlay* overlay = scene_overlay.empty() ? nullptr : &scene_overlay;
    glm::vec2 own_range(0.0f);  // the last view's own relative depth range
    // A movie's frames share one streamer (its chunks stay resident from frame to frame) and
    // show a progress bar instead of a line a view.
    std::shared_ptr<render::ChunkStreamer> shared_streamer;
    bool quiet_views = false;
    const std::optional<config::WallConfig> wall =
        wall_path.empty() ? std::nullopt : std::optional(sync::loadWallConfig(wall_path));
    // Where the wall's foveal insets are: the scene's centres, then --inset's.
    scene::InsetPlacement inset_placement = graph.settings().inset();
    if (!inset_args.empty() && !wall) usage("--inset needs --wall");
    if (wall) {
      for (int i = 0; i < inset_placement.centres_size(); ++i)
        if (const auto why = render::insetPlacementProblem(*wall, inset_placement.centres(i)))
          throw std::runtime_error(scene_path + ": settings.inset.centres[" + std::to_string(i) +
                                   "]: " + *why);
      for (const std::string& arg : inset_args) {
        const size_t eq = arg.rfind('='), comma = arg.rfind(',');
        scene::InsetCentre c;
        char* end = nullptr;
        if (eq == std::string::npos || comma == std::string::npos || comma < eq)
          usage("--inset " + arg + ": give NAME=X,Y (metres)");
        c.set_name(arg.substr(0, eq));
        const std::string xs = arg.substr(eq + 1, comma - eq - 1), ys = arg.substr(comma + 1);
        c.set_x(std::strtod(xs.c_str(), &end));
        if (xs.empty() || *end != '\0') usage("--inset " + arg + ": X is not a number");
        c.set_y(std::strtod(ys.c_str(), &end));
        if (ys.empty() || *end != '\0') usage("--inset " + arg + ": Y is not a number");
        if (const auto why = render::insetPlacementProblem(*wall, c))
          usage("--inset " + arg + ": " + *why);
        bool placed = false;
        for (scene::InsetCentre& old_centre : *inset_placement.mutable_centres())
          if (old_centre.name() == c.name()) old_centre = c, placed = true;
        if (!placed) *inset_placement.add_centres() = c;
      }
    }
    // The viewer's head: the scene's, then --head's (sync/viewer_head.h).
    scene::Settings head_settings;
    if (graph.settings().has_head()) *head_settings.mutable_head() = graph.settings().head();
    if (!head_arg.empty()) {
      if (!wall || !mosaic) usage("--head needs --wall and --mosaic");
      *head_settings.mutable_head() = parseHead(head_arg);
      if (const auto why = sync::headProblem(*wall, head_settings.head()))
        usage("--head " + head_arg + ": head." + *why);
    } else if (wall && head_settings.has_head()) {
      if (const auto why = sync::headProblem(*wall, head_settings.head()))
        throw std::runtime_error(scene_path + ": settings.head." + *why);
    }
    const bool has_head = head_settings.has_head();
    const sync::ViewerHead viewer =
        wall ? sync::viewerHead(*wall, head_settings) : sync::ViewerHead();
    // The slots' weighted pictures of the last --mosaic of a wall with insets (insetDetail()).
    std::vector<render::Image> inset_slots;
    // `weigh`: a foveal inset's slot (render/inset.h), weighed on the GPU as a node weighs it.
    std::unique_ptr<render::InsetPass> inset_pass;
    // --mosaic of a wall with projectors: every tile's blend and warp (the automatic blends
    // computed as each node computes its own), a pass per tile, and the projectors' pictures
    // of the last mosaic (assembleProjectorFrames()).
    std::vector<render::ProjectorMap> projector_maps;
    std::vector<std::unique_ptr<render::ProjectorPass>> projector_passes;
    std::vector<render::Image> projector_frames;
    if (wall && mosaic && render::hasProjectors(*wall)) {
      try {
        projector_maps = render::loadProjectorMaps(*wall);
      } catch (const render::RenderError& e) {
        throw std::runtime_error(wall_path + ": " + e.what());  // bad input: exit 1
      }
      projector_passes.resize(projector_maps.size());
    }
    // `project`: the index of the tile whose projector shows the view (its pass applied as the
    // node applies it), or -1.
    auto renderView = [&](const std::string& name, const render::ViewSetup& v,
                          const render::RenderOptions& view_options,
                          const render::WallSlot* weigh = nullptr, int project = -1) {
      render::ViewRenderer r(v.width, v.height, shared_streamer, stream_options);
      render::RenderStats st;
      render::Image img = r.renderSettled(instances, v, view_options, &st, overlay);
      if (project >= 0 && !projector_maps[size_t(project)].identity()) {
        auto& pass = projector_passes[size_t(project)];
        if (!pass) pass = std::make_unique<render::ProjectorPass>(projector_maps[size_t(project)]);
        pass->run(r.imageBuffer());
        img = pass->read();
      }
      if (weigh) {
        if (!inset_pass) inset_pass = std::make_unique<render::InsetPass>();
        inset_pass->run(r.imageBuffer(), *wall, *weigh, inset_placement);
        img = inset_pass->read();
      }
      own_range = st.relative_depth_range;
      if (!quiet_views)
        std::fprintf(
            stderr,
            "%s: %ux%u, %zu nodes, %llu points, %llu triangles, %.1f MB resident after %zu "
            "frames; last frame %.1f ms (select %.1f, meshes %.1f, depth %.1f, colour "
            "%.1f, resolve %.1f)%s\n",
            name.c_str(), v.width, v.height, st.nodes, (unsigned long long)st.points,
            (unsigned long long)st.triangles, st.stream.resident_bytes / 1e6, st.frames,
            st.totalMs(), st.select_ms, st.mesh_ms, st.depth_ms, st.color_ms, st.resolve_ms,
            st.corrupt_chunks ? (", " + std::to_string(st.corrupt_chunks) +
                                 " corrupt chunks drawn by their ancestors")
                                    .c_str()
                              : "");
      if (stats_file) {
        stats_file << name << "," << v.width << "," << v.height << "," << st.frames << ","
                   << st.cut_nodes << "," << st.nodes << "," << st.points << ","
                   << st.corrupt_chunks << "," << st.stream.resident_chunks << ","
                   << st.stream.resident_bytes << "," << store_bytes << "," << st.select_ms << ","
                   << st.upload_ms << "," << st.depth_ms << "," << st.color_ms << ","
                   << st.resolve_ms << "," << st.readback_ms << "," << st.totalMs() << ","
                   << st.ensembles << "," << st.copies << "\n";
      }
      return img;
    };

    // A corrupt hierarchy page leaves out the nodes below it: the picture is written, but said.
    std::set<const lod::PointStore*> warned;
    auto warnCorrupt = [&] {
      for (const auto& m : instances) {
        if (!m.store) continue;
        const uint64_t pages = m.store->cacheStats().corrupt_pages;
        if (pages > 0 && warned.insert(m.store).second)
          std::fprintf(stderr,
                       "tessera-render: warning: %s: %llu corrupt hierarchy pages; the nodes "
                       "below them are not drawn\n",
                       m.store->path().c_str(), (unsigned long long)pages);
      }
    };
    auto plainViewSized = [&](const config::Camera& c, unsigned w, unsigned h) {
      render::ViewSetup v;
      v.view = render::cameraView(c);
      const auto [lo, hi] = render::worldBounds(instances.front());
      double radius = 0.5 * glm::length(hi - lo);
      double dist = glm::length(glm::dvec3(c.eye().x(), c.eye().y(), c.eye().z()) -
                                glm::dvec3(c.target().x(), c.target().y(), c.target().z()));
      v.projection = glm::perspective(
          glm::radians(fovy), double(w) / h,
          std::max(1e-4 * radius, (dist - 4 * radius) * 0.5 + 1e-6 * radius), dist + 4 * radius);
      v.width = w;
      v.height = h;
      v.eye_world = glm::dvec3(c.eye().x(), c.eye().y(), c.eye().z());
      return v;
    };
    auto plainView = [&](const config::Camera& c) {
      return plainViewSized(c, plain_size.width, plain_size.height);
    };
    // Stereo: the eye `eye_x` metres right of the viewer (0: the mono view), through the wall
    // plane or, for a plain view, the plane through the camera's target.
    auto eyeView = [&](const render::ViewSetup& v, const config::Camera& c, double eye_x) {
      if (eye_x == 0.0) return v;
      const double screen = wall ? wall->eye().z() : glm::length(vec(c.eye()) - vec(c.target()));
      return render::stereoEyeView(v, glm::dvec3(eye_x, 0.0, 0.0), screen);
    };
    // The picture of camera `c` for one eye, as the command line asks: the plain view, the
    // whole wall, the mosaic or one tile.
    auto picture = [&](const config::Camera& c, double eye_x) -> render::Image {
      const std::string eye = eye_x < 0.0 ? "-left" : eye_x > 0.0 ? "-right" : "";
      if (!wall) return renderView("view" + eye, eyeView(plainView(c), c, eye_x), options);
      if (whole)
        return renderView("whole" + eye, eyeView(render::wholeWallView(*wall, c), c, eye_x),
                          options);
      if (mosaic && (wall->insets_size() > 0 || wall->stereo() || has_head)) {
        // The tiles and the insets' slots, each weighted as its node weighs it, then the wall
        // as the master assembles it (render/inset.h). A stereo wall's tiles are seen by the
        // eye asked for (its left one for a mono picture, as the master's screenshot is), with
        // the views the nodes of those slots render; so are every wall's under a head.
        const config::WallConfig shown = render::monoWall(*wall);
        const int tile_eye = eye_x < 0.0 ? -1 : eye_x > 0.0 ? 1 : wall->stereo() ? -1 : 0;
        const std::vector<render::WallSlot> slots = render::wallSlots(shown);
        auto slotView = [&](const render::WallSlot& s) {
          if (!has_head && !wall->stereo()) {
            const render::ViewSetup v = render::slotView(*wall, s, inset_placement, c);
            return s.inset < 0 ? eyeView(v, c, eye_x) : v;
          }
          render::WallSlot seen = s;
          if (s.inset < 0) seen.eye = tile_eye;
          return render::slotView(*wall, seen, inset_placement, c, &viewer);
        };
        const bool weigh = wall->insets_size() > 0;
        render::RenderOptions wall_options = options;
        if (options.relative_depth.enabled && !options.relative_depth.range) {
          std::vector<glm::vec2> ranges;
          for (const auto& s : slots) {
            renderView(s.tile.name() + eye, slotView(s), options);
            ranges.push_back(own_range);
          }
          wall_options.relative_depth.agreed_range = render::wallRange(ranges);
        }
        inset_slots.clear();
        // A head on a wall with projectors: each tile through its projector's pass, as a
        // mono wall's mosaic has it.
        for (const auto& s : slots)
          inset_slots.push_back(renderView(s.tile.name() + eye, slotView(s), wall_options,
                                           weigh ? &s : nullptr,
                                           projector_maps.empty() ? -1 : s.tile_index));
        if (!projector_maps.empty()) projector_frames = inset_slots;
        return render::assembleInsetWall(shown, inset_slots, inset_placement);
      }
      if (mosaic) {
        std::vector<render::Image> tiles;
        render::RenderOptions wall_options = options;
        if (options.relative_depth.enabled && !options.relative_depth.range) {
          // The tiles agree on one relative depth range, as a wall's master has them do: each
          // tile's own range first, then the pictures with the wall's.
          std::vector<glm::vec2> ranges;
          for (const auto& tile : wall->tiles()) {
            renderView(tile.name() + eye, eyeView(render::tileView(*wall, tile, c), c, eye_x),
                       options);
            ranges.push_back(own_range);
          }
          wall_options.relative_depth.agreed_range = render::wallRange(ranges);
        }
        // With projectors each tile's picture is what its projector shows (its blend and warp
        // applied as its node applies them), and the mosaic what the room sees of them.
        for (int t = 0; t < wall->tiles_size(); ++t)
          tiles.push_back(renderView(
              wall->tiles(t).name() + eye,
              eyeView(render::tileView(*wall, wall->tiles(t), c), c, eye_x), wall_options, nullptr,
              projector_maps.empty() ? -1 : t));
        if (!projector_maps.empty()) projector_frames = tiles;
        return render::assembleWallMosaic(*wall, tiles);
      }
      const config::Tile* tile =
          wall->tiles_size() == 1 && tile_name.empty() ? &wall->tiles(0) : nullptr;
      for (const auto& t : wall->tiles()) {
        if (t.name() == tile_name) tile = &t;
      }
      if (!tile)
        usage("--tile '" + tile_name + "' is not a tile of " + wall_path +
              " (give --tile, --mosaic or --whole)");
      return renderView(tile->name() + eye, eyeView(render::tileView(*wall, *tile, c), c, eye_x),
                        options);
    };
    const double half_eye = 0.5 * eye_separation;
    const render::StereoLayout layout = stereo.empty()
                                            ? render::StereoLayout::kPair
                                            : render::parseStereoLayout(stereo, "--stereo");
    // One picture of camera `c`: mono, or both eyes in one image.
    auto framePicture = [&](const config::Camera& c) {
      if (stereo.empty()) return picture(c, 0.0);
      return render::composeStereo(picture(c, -half_eye), picture(c, half_eye), layout);
    };

    // Each previewed scan's whole store in place of its preview: once built (`wait` false:
    // only those built by now), its preview's chunks forgotten by `streamer` when given.
    auto swapPreviews = [&](bool wait, render::ChunkStreamer* streamer) {
      for (PreviewedModel& p : previewed) {
        if (!p.preview || (!wait && !p.preview->finalReady())) continue;
        auto built = lod::PointStore::open(p.preview->finalStore());
        if (streamer) streamer->forget(*stores[p.store]);
        instances[p.instance].store = built.get();
        instances[p.instance].model = render::storeModel(*built);
        stores[p.store] = std::move(built);
        p.preview.reset();
      }
    };
    if (!preview_out.empty()) {
      // The preview is a coarse sample drawn once: discs of its nodes' spacing, without
      // measuring each close point's own splat size (what dominates a volume's first frame).
      const render::StreamerOptions full_options = stream_options;
      if (!previewed.empty()) stream_options.point_splat_sizes = false;
      const render::Image first = framePicture(cam);
      stream_options = full_options;
      render::writePng(preview_out, first);
      std::printf(
          "wrote %s (%ux%u)%s\n", preview_out.c_str(), first.width, first.height,
          previewed.empty() ? ", the final picture: no scan needed a preview" : ", preview");
      std::fflush(stdout);
      swapPreviews(true, nullptr);
    }
    if (win) {
      for (PreviewedModel& p : previewed) p.preview->startBuild();
      cam = interactive(*win, cam, plainView, instances, options, stream_options, overlay, frames,
                        [&](render::ViewRenderer& r) { swapPreviews(false, &r.streamer()); });
      swapPreviews(true, nullptr);
      if (out.empty()) return 0;
    }
    if (path_run)
      return writePathFrames(
          camera_path, fps, movie, frames_dir,
          [&](const config::Camera& c) { return framePicture(c); },
          [&] {
            shared_streamer = std::make_shared<render::ChunkStreamer>(stream_options);
            quiet_views = true;
          },
          warnCorrupt);
    if (!poster.empty()) {
      render::ViewSetup full;
      if (!wall) {
        full = plainViewSized(cam, poster_size.width, poster_size.height);
      } else {
        // The whole wall at the poster's size: the same window, more pixels on it.
        full = render::wholeWallView(*wall, cam);
        const long fit_h = std::lround(double(poster_size.width) * full.height / full.width);
        if (std::abs(long(poster_size.height) - fit_h) > 1)
          usage("--poster " + poster + ": the wall's whole view is " + std::to_string(full.width) +
                "x" + std::to_string(full.height) + "; give " + std::to_string(poster_size.width) +
                "x" + std::to_string(fit_h));
        full.pixels_per_metre *= double(poster_size.width) / full.width;
        full.width = poster_size.width;
        full.height = poster_size.height;
      }
      std::vector<std::pair<double, std::string>> eyes = {{0.0, out}};
      if (!stereo.empty())
        eyes = {{-half_eye, render::stereoPairPath(out, false)},
                {half_eye, render::stereoPairPath(out, true)}};
      for (const auto& [eye_x, file] : eyes) {
        if (eye_x != 0.0) cli::refuseOverwrite(file, read, "-o");
        render::PngStripWriter writer(file, full.width, full.height);
        std::optional<Progress> progress;
        const render::PosterStats st = render::renderPoster(
            instances, eyeView(full, cam, eye_x), options, plan,
            [&](std::span<const uint8_t> rgba, uint32_t, uint32_t rows) {
              writer.writeRows(rgba, rows);
            },
            stream_options, overlay,
            [&](size_t done, size_t total) {
              // Pixels rendered (twice the poster's when the parts agree on a range first).
              const uint64_t part_px =
                  uint64_t(full.width) * full.height / (uint64_t(plan.columns) * plan.rows);
              if (!progress) progress.emplace("poster " + file, total * part_px, " px");
              progress->update(done * part_px);
            });
        if (progress) progress->finish();
        warnCorrupt();
        writer.finish();
        std::printf("wrote %s (%ux%u, %ux%u parts of up to %ux%u, guard band %u px)\n",
                    file.c_str(), full.width, full.height, plan.columns, plan.rows, plan.part_width,
                    plan.part_height, st.max_band);
      }
      return 0;
    }
    if (layout == render::StereoLayout::kPair && !stereo.empty()) {
      for (const double eye_x : {-half_eye, half_eye}) {
        const std::string file = render::stereoPairPath(out, eye_x > 0.0);
        cli::refuseOverwrite(file, read, "-o");
        const render::Image img = picture(cam, eye_x);
        warnCorrupt();
        render::writePng(file, img);
        std::printf("wrote %s (%ux%u)\n", file.c_str(), img.width, img.height);
      }
      return 0;
    }
    const render::Image result = framePicture(cam);
    warnCorrupt();
    render::writePng(out, result);
    std::printf("wrote %s (%ux%u)\n", out.c_str(), result.width, result.height);
    if (!projector_frames.empty() && stereo.empty()) {
      // What each projector shows, side by side, as the master writes it.
      const std::string file = render::projectorFramesPath(out);
      cli::refuseOverwrite(file, read, "-o");
      const render::Image shown = render::assembleProjectorFrames(*wall, projector_frames);
      render::writePng(file, shown);
      std::printf("wrote %s (%ux%u)\n", file.c_str(), shown.width, shown.height);
    }
    if (mosaic && !inset_slots.empty() && stereo.empty()) {
      // Each inset at its own density beside the wall, as the master writes it.
      for (int i = 0; i < wall->insets_size(); ++i) {
        const config::Inset& in = wall->insets(i);
        for (int eye : in.stereo() ? std::vector<int>{-1, 1} : std::vector<int>{0}) {
          const std::string file = render::insetPicturePath(out, in.name(), eye);
          cli::refuseOverwrite(file, read, "-o");
          const render::Image detail =
              render::insetDetail(render::monoWall(*wall), inset_slots, inset_placement, i, eye);
          render::writePng(file, detail);
          std::printf("wrote %s (%ux%u)\n", file.c_str(), detail.width, detail.height);
        }
      }
    }
    return 0;
  } catch (const cli::UsageError&) {
    throw;                                // cli::runMain: exit 2
  } catch (const media::VideoError& e) {  // the movie cannot be written
    std::fprintf(stderr, "tessera-render: %s\n", e.what());
    return 3;
  } catch (const render::RenderError& e) {  // no usable GL, or the PNG cannot be written
    std::fprintf(stderr, "tessera-render: %s\n", e.what());
    return 3;
  } catch (const std::runtime_error&
               e) {  // bad config, store or scan (ConfigError, StoreError, ReadError)
    std::fprintf(stderr, "tessera-render: %s\n", e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runMain("tessera-render", [&] { return run(argc, argv); });
}
