// tessera-master: owns the scene and drives the wall's render nodes (master/). Parses
// the command line and wires a cluster link to master::Master (master/master.h), which does the
// rest. Inside one MPI job (MPMD, the master first):
//   mpirun -np 1 tessera-master --wall W.json --scene S.json [...] : -np K tessera-node --headless
// or over ZeroMQ, nodes started on their own hosts in any order, at any time:
//   tessera-master --wall W.json --scene S.json --transport zmq --listen tcp://*:7400 [...]
//   tessera-node --master tcp://HOST:7400 [--tile NAME] [--headless]
#include <CLI/CLI.hpp>

#include <tessera/core/cli.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <utility>
#include <vector>

#include <tessera/collab/curve.h>
#include <tessera/collab/site_hub.h>
#include <tessera/master/master.h>
#include <tessera/media/voice_alsa.h>
#include <tessera/sync/config.h>
#include <tessera/sync/mpi_link.h>
#include <tessera/sync/zmq_link.h>

namespace {

using namespace tessera;

/// MPI nodes wait in their join: answer them (refuse) so the whole job ends with the message.
void refuseEveryone(sync::MasterLink& link, const std::string& reason) {
  const sync::LinkEvents events = link.poll(sync::LinkClock::now());
  for (const auto& [peer, hello] : events.joins) link.refuse(peer, reason);
  if (!link.canDropNodes())
    (void)link.collect(0, {}, sync::LinkClock::duration(0), sync::LinkClock::now());
  link.quit(master::kExitStart, reason);
}

int run(int argc, char** argv) {
  master::MasterOptions o;
  std::string transport = "mpi", listen = "tcp://*:7400";
  double timeout_s = 120.0;
  CLI::App app{
      "tessera-master: owns the scene and drives the wall's render nodes, over MPI (started by "
      "mpirun before the nodes) or ZeroMQ (nodes join at any time)"};
  app.footer(
      "Ctrl-C or SIGTERM ends the session at the frame at work, as the end of its script does "
      "(its screenshot and outputs written, nodes and sites told). Another signal within a "
      "second is the same request (a supervisor such as timeout signals the process and its "
      "group); one a second or more later ends the master at once.");
  app.add_option("--wall", o.wall, "Wall configuration (JSON)")->required();
  app.add_option("--scene", o.scene, "Scene configuration (JSON): models, camera, shading")
      ->required();
  app.add_option("--script", o.script, "Camera path with timed actions (configs/paths/*.json)");
  app.add_option("--frames", o.frames,
                 "Run this many frames, deterministic: script time = frame / fps, every frame "
                 "rendered complete (0: real time until the script or console ends)")
      ->check(cli::integerRange(0, 1 << 30));
  app.add_option("--fps", o.fps,
                 "With --frames or --path: script frames per second (fewer: coarser steps)")
      ->check(cli::finiteRange(0.1, 1000.0))
      ->capture_default_str();
  app.add_option("--max-fps", o.max_fps,
                 "Start frames at most this often, real time (0: as fast as the nodes go)")
      ->check(cli::finiteRange(0.0, 1000.0))
      ->capture_default_str();
  std::string film_path, movie_size;
  app.add_option(
      "--path", film_path,
      "Film this camera path (configs/paths/; its actions applied, as --script's) with --movie "
      "or --frames-dir: frame i at i / fps seconds, as many as its duration holds, every frame "
      "settled on every node and read back");
  app.add_option("--movie", o.movie,
                 "With --path: write the wall's picture of every frame as an MP4 movie (as "
                 "tessera-render --movie: its sides must be even), with a progress bar");
  app.add_option("--frames-dir", o.frames_dir,
                 "With --path: write every frame's wall picture as DIR/frame-000000.png, ... (made "
                 "if missing)");
  app.add_option("--size", movie_size,
                 "With --movie or --frames-dir: the frames' size WxH (default: the wall "
                 "screenshot's), the wall's picture scaled to it");
  app.add_option("--screenshot", o.screenshot, "Write the wall picture (PNG) of the last frame");
  app.add_option("--stats", o.stats, "Per-frame, per-tile statistics (CSV)");
  app.add_option("--out-dir", o.out_dir, "Where the script's screenshot paths are relative to")
      ->capture_default_str();
  app.add_flag("--console", o.console,
               "A window with the whole wall at low resolution and one-button navigation");
  app.add_option("--console-screenshot", o.console_screenshot,
                 "With --console: write what the console window shows at the last frame (PNG)");
  app.add_option("--console-width", o.console_width, "Console width, pixels")
      ->check(cli::integerRange<uint32_t>(64, 4096))
      ->capture_default_str();
  app.add_option("--annotations", o.annotations,
                 "The annotation database (SQLite, made if missing): its notes, layers, "
                 "measurements and selections are in the scene, and what is measured, selected "
                 "and noted in the session is stored in it (tessera-annotate reads it)");
  app.add_option("--splat-scale", o.splat_scale, "As tessera-render --splat-scale")
      ->check(cli::finiteRange(0.25, 8.0))
      ->capture_default_str();
  app.add_option("--gpu-budget-mb", o.gpu_budget_mb, "Per node GPU bytes for chunks, MiB")
      ->check(cli::finiteRange(1.0, 1e6))
      ->capture_default_str();
  app.add_option("--transport", transport,
                 "mpi: one mpirun job, every node known at start, a lost node ends the job; "
                 "zmq: nodes join, drop out and rejoin (--listen)")
      ->check(CLI::IsMember({"mpi", "zmq"}))
      ->capture_default_str();
  app.add_option("--listen", listen, "zmq: the endpoint the nodes connect to")
      ->capture_default_str();
  app.add_option("--node-timeout", o.node_timeout_ms,
                 "zmq: ms a live node's report may be late before its tile is dropped (0: five "
                 "times the slowest node's median frame, at least 1000)")
      ->check(cli::finiteRange(0.0, 3.6e6))
      ->capture_default_str();
  app.add_option("--join-wait", o.join_wait_s,
                 "zmq: seconds to wait for a node per tile before the first frame")
      ->check(cli::finiteRange(0.0, 3600.0))
      ->capture_default_str();
  app.add_option("--first-frame-timeout", o.first_frame_timeout_s,
                 "Seconds a node may take to start and render its first frame (cold caches)")
      ->check(cli::finiteRange(0.1, 3600.0))
      ->capture_default_str();
  collab::SiteHubOptions sites;
  sites.endpoint.clear();
  app.add_option("--sites", sites.endpoint,
                 "Remote sites join here over encrypted ZeroMQ (tessera-site), e.g. tcp://*:7401; "
                 "needs --site-key and --allow");
  app.add_option(
      "--site-key", sites.key_file,
      "The master's CURVE key pair for --sites (tessera-site keygen -o FILE; mode 0600)");
  app.add_option("--allow", sites.allow_list,
                 "The sites' public keys that may join, one per line with an optional name (read "
                 "again when it changes)");
  app.add_option("--site-timeout", sites.silent_timeout_s,
                 "Seconds a site may be silent before its avatar goes (a closed connection: at "
                 "once)")
      ->check(cli::finiteRange(0.5, 3600.0))
      ->capture_default_str();
  double chunk_rate_mbit = 100.0, chunk_total_mbit = 0.0;
  app.add_option("--chunks", sites.chunks_endpoint,
                 "Serve the scene's stores to sites that do not have them (chunks on demand, "
                 "over CURVE with --sites' keys and allow list), e.g. tcp://*:7402; needs --sites");
  app.add_flag("--voice", sites.voice,
               "Voice between the sites and the wall (Opus): the master mixes what sites say, "
               "each site hears the others and the wall's microphone; needs --sites");
  app.add_option("--audio-in", sites.audio_in,
                 "With --voice: the wall room's microphone, a WAV file (16-bit PCM) or a sound "
                 "device through ALSA (alsa:default, alsa:hw:0,0, ...)");
  app.add_option("--audio-out", sites.audio_out,
                 "With --voice: what the wall room's speakers play (every site), written as WAV "
                 "at the end, or played on a sound device through ALSA (alsa:default, ...)");
  app.add_option("--video-cap", sites.video_cap_kbps,
                 "Video insets: each site's video is held to this many kbit/s; chunks over it "
                 "are dropped (said once a second) and the stream recovers at its next refresh")
      ->check(cli::finiteRange(10, 1e6))
      ->capture_default_str();
  std::string video_screen;
  app.add_option("--video-screen", video_screen,
                 "Video insets pinned to the screen instead of beside the avatars: X,Y,W, the "
                 "first inset's lower-left corner and width in fractions of the wall (the next "
                 "to its right; heights follow the pictures), e.g. 0.72,0.04,0.24");
  app.add_option("--chunk-rate", chunk_rate_mbit,
                 "With --chunks: each site's bandwidth for chunks, Mbit/s (a token bucket)")
      ->check(cli::finiteRange(0.01, 1e5))
      ->capture_default_str();
  app.add_option("--chunk-total-rate", chunk_total_mbit,
                 "With --chunks: the bandwidth for chunks of all sites together, Mbit/s, shared "
                 "in turn (the master's uplink; 0: only each site's --chunk-rate)")
      ->check(cli::finiteRange(0.0, 1e6))
      ->capture_default_str();
  app.add_option("--timeout", timeout_s,
                 "mpi: seconds a node rank may keep the master waiting (to join, report or take "
                 "a message) before the job is aborted, naming it (exit 4)")
      ->check(cli::finiteRange(0.1, 86400.0))
      ->capture_default_str();

  // MPI removes its own arguments in MPI_Init, so with mpirun the transport comes first: a
  // command line that does not parse still has to reach the nodes waiting in their join.
  bool want_mpi = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--transport" && i + 1 < argc && std::string(argv[i + 1]) == "zmq") ||
        a == "--transport=zmq")
      want_mpi = false;
  }
  std::unique_ptr<sync::MpiTransport> mpi;
  std::unique_ptr<sync::MasterLink> link;
  if (want_mpi) {
    try {
      mpi = std::make_unique<sync::MpiTransport>(&argc, &argv, "tessera-master", timeout_s);
    } catch (const sync::TransportError& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 1;
    }
    if (mpi->rank() != 0)
      mpi->abort(2,
                 "tessera-master must be rank 0: start it first, `mpirun -np 1 tessera-master "
                 "... : -np K tessera-node`");
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = cli::exitCode(app, e, "tessera-master");
    if (mpi) {
      sync::MpiMasterLink l(*mpi);
      refuseEveryone(l, "the master's command line: " + std::string(e.what()));
    }
    return code;
  }
  // What the master writes must never be what it reads (by any path).
  try {
    const bool filming = !o.movie.empty() || !o.frames_dir.empty();
    if (!film_path.empty() != filming)
      throw cli::UsageError(film_path.empty()
                                ? "--movie and --frames-dir film a camera path: give --path P.json"
                                : "--path needs --movie OUT.mp4 or --frames-dir DIR");
    if (!film_path.empty() && (!o.script.empty() || o.frames > 0 || o.console))
      throw cli::UsageError(
          "--path films the path: drop --script, --frames (its duration and --fps give the "
          "frames) and --console");
    if (!movie_size.empty()) {
      if (!filming) throw cli::UsageError("--size needs --movie or --frames-dir");
      const cli::Size size = cli::parseSize(movie_size, "--size", 16384);
      o.movie_width = size.width;
      o.movie_height = size.height;
    }
    if (!film_path.empty()) o.script = film_path;
    std::vector<std::filesystem::path> read{o.wall, o.scene, o.script};
    try {  // and the scene's stores (a bad scene is reported by prepare())
      const scene::SceneFile scene_file = sync::loadSceneFile(o.scene);
      for (const auto& n : scene_file.nodes()) {
        if (n.has_model()) read.push_back(n.model().store());
      }
    } catch (const sync::ConfigError&) {
    }
    for (const auto& [path, option] :
         {std::pair{&o.screenshot, "--screenshot"}, std::pair{&o.stats, "--stats"},
          std::pair{&o.console_screenshot, "--console-screenshot"},
          std::pair{&o.annotations, "--annotations"}, std::pair{&o.movie, "--movie"}}) {
      if (!path->empty()) cli::refuseOverwrite(*path, read, option);
    }
    // Outputs written at the end (or during the run) are refused now when they could not be.
    for (const auto& [path, option] :
         {std::pair{&o.screenshot, "--screenshot"}, std::pair{&o.stats, "--stats"},
          std::pair{&o.console_screenshot, "--console-screenshot"},
          std::pair{&o.movie, "--movie"}}) {
      if (!path->empty()) cli::refuseUnwritable(*path, option);
    }
    if (!o.frames_dir.empty()) {
      std::error_code ec;
      std::filesystem::create_directories(o.frames_dir, ec);
      if (ec || !std::filesystem::is_directory(o.frames_dir))
        throw cli::UsageError("--frames-dir " + o.frames_dir + ": not a folder that can be made" +
                              (ec ? ": " + ec.message() : ""));
    }
    if (!sites.audio_out.empty() && !media::alsaDeviceOf(sites.audio_out))
      cli::refuseUnwritable(sites.audio_out, "--audio-out");
  } catch (const cli::UsageError& e) {
    std::fprintf(stderr, "tessera-master: %s\n", e.what());
    if (mpi) {
      sync::MpiMasterLink l(*mpi);
      refuseEveryone(l, e.what());
    }
    return cli::kExitBadCommandLine;
  }
  if (!sites.endpoint.empty() && (sites.key_file.empty() || sites.allow_list.empty())) {
    const std::string why =
        "--sites needs --site-key and --allow (remote sites are never let in "
        "without encryption and an allow list)";
    std::fprintf(stderr, "tessera-master: %s\n", why.c_str());
    if (mpi) {
      sync::MpiMasterLink l(*mpi);
      refuseEveryone(l, why);
    }
    return cli::kExitBadCommandLine;
  }
  if (sites.endpoint.empty() && (!sites.key_file.empty() || !sites.allow_list.empty())) {
    std::fprintf(stderr, "tessera-master: --site-key and --allow need --sites ENDPOINT\n");
    if (mpi) {
      sync::MpiMasterLink l(*mpi);
      refuseEveryone(l, "--site-key and --allow need --sites");
    }
    return cli::kExitBadCommandLine;
  }
  if (sites.endpoint.empty() && !sites.chunks_endpoint.empty()) {
    std::fprintf(stderr,
                 "tessera-master: --chunks needs --sites ENDPOINT (its keys and allow "
                 "list admit the sites)\n");
    if (mpi) {
      sync::MpiMasterLink l(*mpi);
      refuseEveryone(l, "--chunks needs --sites");
    }
    return cli::kExitBadCommandLine;
  }
  const char* voice_problem =
      (!sites.audio_in.empty() || !sites.audio_out.empty()) && !sites.voice
          ? "--audio-in and --audio-out need --voice"
          : (sites.endpoint.empty() && sites.voice ? "--voice needs --sites ENDPOINT" : nullptr);
  if (voice_problem) {
    std::fprintf(stderr, "tessera-master: %s\n", voice_problem);
    if (mpi) {
      sync::MpiMasterLink l(*mpi);
      refuseEveryone(l, voice_problem);
    }
    return cli::kExitBadCommandLine;
  }
  sites.chunk_bytes_per_s = chunk_rate_mbit * 1e6 / 8.0;
  sites.chunk_total_bytes_per_s = chunk_total_mbit * 1e6 / 8.0;
  if (!video_screen.empty()) {
    float x = -1, y = -1, w = -1;
    char tail = 0;
    if (std::sscanf(video_screen.c_str(), "%f,%f,%f%c", &x, &y, &w, &tail) != 3 ||
        !(x >= 0 && x < 1) || !(y >= 0 && y < 1) || !(w > 0 && w <= 1) || x + w > 1.0001f) {
      std::fprintf(stderr,
                   "tessera-master: --video-screen %s: expected X,Y,W, fractions of the wall "
                   "with X and Y in [0, 1), W in (0, 1] and X + W <= 1\n",
                   video_screen.c_str());
      return cli::kExitBadCommandLine;
    }
    sites.video_screen = true;
    sites.screen_x = x;
    sites.screen_y = y;
    sites.screen_width = w;
  }
  if (mpi) {
    mpi->setTimeout(timeout_s);
    auto l = std::make_unique<sync::MpiMasterLink>(*mpi);
    if (l->nodes() == 0) {
      std::fprintf(stderr,
                   "tessera-master: no render nodes; start them after the master: mpirun -np 1 "
                   "tessera-master ... : -np K tessera-node --headless\n");
      return 1;
    }
    link = std::move(l);
  } else {
    try {
      sync::ZmqLinkOptions zo;
      zo.max_message_bytes = int64_t(16384) * 16384 * 4 + (int64_t(1) << 20);
      auto z = std::make_unique<sync::ZmqMasterLink>(listen, zo);
      std::printf("tessera-master: listening on %s\n", z->endpoint().c_str());
      std::fflush(stdout);
      link = std::move(z);
    } catch (const sync::LinkError& e) {
      std::fprintf(stderr, "tessera-master: --listen %s: %s\n", listen.c_str(), e.what());
      return 1;
    }
  }

  master::Master m(*link, o);
  try {
    m.prepare();
  } catch (const std::exception& e) {  // StartError, ConfigError, out of memory
    std::fprintf(stderr, "%s\n", e.what());
    refuseEveryone(*link, e.what());
    return master::kExitStart;
  }
  std::unique_ptr<collab::SiteHub> hub;
  if (!sites.endpoint.empty()) {
    try {
      sites.wall = m.wall();  // sites' heads are checked against it
      hub = std::make_unique<collab::SiteHub>(sites);
      std::printf("tessera-master: remote sites join on %s\n", hub->endpoint().c_str());
      if (!sites.chunks_endpoint.empty())
        std::printf("tessera-master: chunks served on %s (%g Mbit/s per site%s)\n",
                    hub->chunksEndpoint().c_str(), chunk_rate_mbit,
                    chunk_total_mbit > 0
                        ? (", " + std::to_string(chunk_total_mbit) + " Mbit/s for all").c_str()
                        : "");
      std::fflush(stdout);
      m.setParticipants(hub.get());
      hub->setAnnotations(m.annotations());
    } catch (const std::exception& e) {  // KeyError, a busy port
      std::fprintf(stderr, "tessera-master: --sites: %s\n", e.what());
      refuseEveryone(*link, e.what());
      return master::kExitStart;
    }
  }
  try {
    m.openConsole();
    return m.run();
  } catch (const std::exception& e) {  // the console's stores, the stats file, out of memory
    std::fprintf(stderr, "tessera-master: %s\n", e.what());
    if (mpi) mpi->abort(1, "stopping the wall");
    link->quit(1, e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  tessera::cli::catchStopSignals();  // Ctrl-C, SIGTERM: the session ends with the frame at work
  return tessera::cli::runMain("tessera-master", [&] { return run(argc, argv); });
}
