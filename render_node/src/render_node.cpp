#include <tessera/render_node/render_node.h>

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include <tessera/core/stopwatch.h>
#include <tessera/render/frame_target.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/inset.h>
#include <tessera/render/projector_pass.h>
#include <tessera/render/scene_draw_list.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/render/video_textures.h>
#include <tessera/render/view_renderer.h>
#include <tessera/render/window.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/viewer_head.h>
#include <tessera/sync/wire.h>

namespace tessera::render_node {

namespace {

using Clock = sync::LinkClock;

/// A failure with the code the master reports.
struct NodeError : std::runtime_error {
  NodeError(cluster::NodeFailure f, const std::string& what)
      : std::runtime_error(what), failure(f) {}
  cluster::NodeFailure failure;
};

std::string hostName() {
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) != 0) return "unknown";
  return name;
}

// Set by SIGCONT. A node that was stopped (SIGSTOP, a debugger, a frozen VM) finds on resuming
// that its own heartbeat timer expired while it slept, and takes that for a dead master; this
// flag tells the two apart, so it joins again instead of exiting. The one global of the node:
// a signal handler can only set a flag.
volatile sig_atomic_t gContinued = 0;

void onContinue(int) {
  gContinued = 1;
}

Clock::time_point after(double seconds) {
  return Clock::now() + std::chrono::microseconds(int64_t(seconds * 1e6));
}

}  // namespace

struct RenderNode::Impl {
  sync::NodeLink& link;
  NodeOptions opt;
  std::string who = "tessera-node";
  cluster::ClusterSetup setup;
  const config::Tile* tile = nullptr;  // slot.tile once started
  /// The wall's part this node drives: a tile or an eye of a foveal inset (render/inset.h).
  render::WallSlot slot;
  std::unique_ptr<render::Window> window;
  std::unique_ptr<render::GlContext> context;
  sync::SceneGraph graph;
  render::SceneDrawList models;
  std::span<const render::ModelInstance> instances;  // the draw list's, until its next update
  render::SceneOverlay overlay;                      // sketches, avatars, annotations, videos
  std::unique_ptr<render::VideoTextures> videos;     // the sites' video (needs the context)
  std::unique_ptr<render::ViewRenderer> renderer;    // destroyed first: needs the context
  /// The tile's projector: blend and warp applied to every frame (none: the frame as drawn).
  std::unique_ptr<render::ProjectorPass> projector;
  /// Foveal insets: this slot's weights applied to every frame (none: a wall without insets).
  std::unique_ptr<render::InsetPass> inset_pass;
  /// A node of both eyes (render::kBothEyes): the two eyes side by side, shown and read back.
  render::GlBuffer pair;
  cluster::NodeStatus status;                        // NODE_OK until something fails
  uint64_t reported = 0;                             // the last frame reported
  Clock::time_point reported_at;
  double barrier_ms = 0, present_ms = 0;  // of the previous frame, sent with the next report
  uint64_t video_errors = 0;              // decoding errors already said
  Clock::time_point video_said;           // when a video problem was last said
  /// The relative depth range the wall agreed on, from the last frame message (if any).
  std::optional<glm::vec2> agreed_relative_depth;

  Impl(sync::NodeLink& l, NodeOptions o) : link(l), opt(std::move(o)) {}

  ~Impl() {
    inset_pass.reset();
    pair = render::GlBuffer();
    projector.reset();
    renderer.reset();
    videos.reset();
  }

  /// This node's view: its tile, stereo eye or foveal inset where the scene places it, seen from
  /// the scene's viewer head (sync/viewer_head.h).
  /// A head the master sent behind a tile (its gates refuse one) is refused here too.
  /// A node of both eyes (render::kBothEyes) draws each eye's view in turn (`drawn`).
  render::ViewSetup slotView(const render::WallSlot& drawn) const {
    if (graph.settings().has_head())
      if (const auto why = sync::headProblem(setup.wall(), graph.settings().head()))
        throw NodeError(cluster::NODE_BAD_FRAME, "settings.head." + *why);
    const sync::ViewerHead head = sync::viewerHead(setup.wall(), graph.settings());
    return render::slotView(setup.wall(), drawn, graph.settings().inset(), graph.camera(), &head);
  }
  /// The slot drawn: this node's, or its left eye when it draws both.
  render::WallSlot drawnSlot(int eye = -1) const {
    return slot.eye == render::kBothEyes ? render::eyeOfSlot(setup.wall(), slot, eye) : slot;
  }

  /// Video insets: the frame's video packets to the streams this tile shows, the
  /// new pictures to their textures; a texture made or resized rebuilds the overlay.
  void applyMedia(const cluster::FrameMessage& frame) {
    if (!videos || (frame.media_size() == 0)) return;
    const render::ViewSetup view = slotView(drawnSlot());
    videos->setShown(render::shownVideoSources(graph, view, overlay.options()));
    // A master sends what its sites sent in one frame period: thousands would be an error.
    const int count = std::min(frame.media_size(), 4096);
    for (int i = 0; i < count; ++i) {
      const std::string& m = frame.media(i);
      if (auto why = videos->receive({reinterpret_cast<const uint8_t*>(m.data()), m.size()}))
        noteVideoProblem(*why);
    }
    const render::VideoTextureStats st = videos->stats();
    if (st.errors != video_errors) {
      video_errors = st.errors;
      noteVideoProblem(st.last_problem);
    }
    if (videos->upload()) {
      overlay.invalidate();
      overlay.update(graph, sync::SceneChanges());
    }
  }

  /// Bad video is the sites' problem, not this node's: said at most once a second, and the
  /// inset keeps its last good picture.
  void noteVideoProblem(const std::string& why) {
    const auto now = Clock::now();
    if (now - video_said < std::chrono::seconds(1)) return;
    video_said = now;
    std::fprintf(stderr, "%s: %s (the inset keeps its last good picture)\n", who.c_str(),
                 why.c_str());
  }

  void sayVideoStats() const {
    if (!videos) return;
    const render::VideoTextureStats st = videos->stats();
    if (st.packets == 0) return;
    std::printf(
        "%s: video: %llu packets (%llu refused), %llu pictures decoded, %llu access "
        "units skipped (not shown or waiting for a key), %llu decoding errors, %llu "
        "lost\n",
        who.c_str(), (unsigned long long)st.packets, (unsigned long long)st.refused,
        (unsigned long long)st.decoded, (unsigned long long)st.skipped,
        (unsigned long long)st.errors, (unsigned long long)st.lost);
    std::fflush(stdout);
  }

  void fail(cluster::NodeFailure code, const std::string& why) {
    if (status.code() != cluster::NODE_OK) return;
    status.set_code(code);
    status.set_message(why);
    std::fprintf(stderr, "%s: %s\n", who.c_str(), why.c_str());
  }

  /// `settled`: waits for see-through samples being built (SceneDrawList::finishSampling).
  void updateModels(const sync::SceneChanges& changes, bool settled = false) {
    overlay.update(graph, changes);  // rebuilt only when nodes changed
    try {
      render::ChunkStreamer* streamers[] = {renderer ? &renderer->streamer() : nullptr};
      instances = models.update(graph, changes, streamers);
      if (settled && models.sampling()) instances = models.finishSampling(graph, streamers);
    } catch (const lod::StoreError& e) {
      throw NodeError(cluster::NODE_BAD_STORE, e.what());
    }
  }

  /// Takes a welcome: the tile, a GL context (window or headless), the replica, stores and
  /// renderer. A node that joins again keeps its context, stores and resident chunks.
  void start(cluster::ClusterSetup s) {
    const bool same_size = tile && renderer && s.wall().tiles_size() > 0;
    const uint32_t old_w = tile ? tile->pixel_width() : 0, old_h = tile ? tile->pixel_height() : 0;
    setup = std::move(s);
    tile = nullptr;
    for (const render::WallSlot& w : render::wallSlots(setup.wall())) {
      if (w.tile.name() != setup.tile()) continue;
      slot = w;
      tile = &slot.tile;
    }
    if (!tile)
      throw NodeError(cluster::NODE_BAD_TILE,
                      "the master gave tile '" + setup.tile() + "', which its wall does not have");
    who = "tessera-node " + tile->name();
    if (tile->pixel_width() == 0 || tile->pixel_height() == 0 || tile->pixel_width() > 16384 ||
        tile->pixel_height() > 16384)
      throw NodeError(cluster::NODE_BAD_TILE,
                      "tile " + tile->name() + " is " + std::to_string(tile->pixel_width()) + "x" +
                          std::to_string(tile->pixel_height()) + " pixels (1..16384 each way)");
    // The master's numbers are checked as its command line's are (0: the default).
    if (!(setup.splat_scale() == 0.0f ||
          (setup.splat_scale() >= 0.25f && setup.splat_scale() <= 8.0f)))
      throw NodeError(cluster::NODE_BAD_FRAME, "the master's splat scale " +
                                                   std::to_string(setup.splat_scale()) +
                                                   " is not in [0.25, 8]");
    try {
      if (!window && !context) {
        if (!opt.headless) {
          try {
            window = render::Window::open(tile->pixel_width(), tile->pixel_height(), who);
          } catch (const render::RenderError& e) {
            std::fprintf(stderr, "%s: %s; rendering headless\n", who.c_str(), e.what());
          }
        }
        if (!window) context = render::GlContext::createHeadless();
      }
    } catch (const render::RenderError& e) {
      throw NodeError(cluster::NODE_NO_GL, e.what());
    }
    if (!videos) videos = std::make_unique<render::VideoTextures>();
    {
      // Screen-pinned insets are placed on the wall's extent; this tile shows its own part.
      render::SceneOverlayOptions so = overlay.options();
      so.screen_wall = render::wallExtent(setup.wall());
      so.screen_view =
          glm::dvec4(tile->x(), tile->y(), tile->x() + tile->width(), tile->y() + tile->height());
      so.view_px = glm::dvec2(drawnSlot().tile.pixel_width(), drawnSlot().tile.pixel_height());
      so.video_texture = [this](uint32_t source) { return videos->texture(source); };
      overlay.setOptions(so);
    }
    try {
      graph = sync::SceneGraph();
      graph.apply(setup.snapshot());
    } catch (const sync::SyncError& e) {
      throw NodeError(cluster::NODE_BAD_FRAME, e.what());
    }
    updateModels(sync::SceneChanges::all());
    projector.reset();
    inset_pass.reset();
    if (setup.wall().insets_size() > 0) {
      try {
        inset_pass = std::make_unique<render::InsetPass>();
      } catch (const render::RenderError& e) {
        throw NodeError(cluster::NODE_NO_GL, e.what());
      }
    }
    if (slot.inset < 0 && render::hasProjectors(setup.wall())) {
      // The projector's blend and warp from the wall's files (paths as the master read them).
      int index = 0;
      while (setup.wall().tiles(index).name() != tile->name()) ++index;
      try {
        const std::vector<render::ProjectorMap> maps =
            render::loadProjectorMaps(setup.wall(), true, index);
        if (!maps[size_t(index)].identity())
          projector = std::make_unique<render::ProjectorPass>(maps[size_t(index)]);
      } catch (const render::RenderError& e) {
        throw NodeError(cluster::NODE_BAD_TILE, e.what());
      }
    }
    if (same_size && old_w == tile->pixel_width() && old_h == tile->pixel_height()) return;
    render::StreamerOptions stream;
    if (setup.gpu_budget_bytes() > 0) stream.budget_bytes = setup.gpu_budget_bytes();
    // Any model may turn see-through during the session; only chunks drawn see-through are
    // measured (ChunkUse::kSeeThrough), the others cost nothing for it.
    stream.density_ratios = true;
    renderer.reset();
    try {
      // A node of both eyes renders each at the tile's size into its half of `pair`.
      const config::Tile& drawn = drawnSlot().tile;
      renderer = std::make_unique<render::ViewRenderer>(drawn.pixel_width(), drawn.pixel_height(),
                                                        nullptr, stream);
      pair = slot.eye == render::kBothEyes
                 ? render::GlBuffer(size_t(tile->pixel_width()) * tile->pixel_height() * 4, nullptr)
                 : render::GlBuffer();
    } catch (const render::RenderError& e) {
      throw NodeError(cluster::NODE_NO_GL, e.what());
    }
  }

  /// Applies one frame to the replica (every frame, also those not rendered).
  void apply(const cluster::FrameMessage& frame) {
    if (status.code() != cluster::NODE_OK) return;
    try {
      // A settled frame (pixels asked for, a deterministic run) draws see-through meshes from
      // their samples, waiting for them if they are being built.
      updateModels(graph.apply(sync::parseFrame(frame.frame())),
                   frame.read_back() || setup.settled());
      applyMedia(frame);
      agreed_relative_depth.reset();
      if (frame.relative_depth_range_size() == 2 &&
          frame.relative_depth_range(0) < frame.relative_depth_range(1) &&
          std::isfinite(frame.relative_depth_range(0)) &&
          std::isfinite(frame.relative_depth_range(1)))
        agreed_relative_depth =
            glm::vec2(frame.relative_depth_range(0), frame.relative_depth_range(1));
    } catch (const render::RenderError& e) {
      fail(cluster::NODE_RENDER, std::string("video textures: ") + e.what());
    } catch (const sync::SyncError& e) {
      fail(cluster::NODE_BAD_FRAME, e.what());
    } catch (const NodeError& e) {
      fail(e.failure, e.what());
    }
  }

  /// Renders the replica's current frame and reports it.
  void renderAndReport(bool read_back) {
    cluster::NodeReport r;
    r.set_frame(graph.frameNumber());
    if (status.code() == cluster::NODE_OK) {
      const auto start_time = Clock::now();
      try {
        render::RenderOptions options = render::SceneDrawList::options(
            graph, setup.splat_scale() > 0 ? setup.splat_scale() : 2.0f);
        options.highlights = overlay.highlights();  // selections, tinted on every tile
        options.relative_depth.agreed_range = agreed_relative_depth;
        render::RenderStats rs;
        // While this frame renders the link says now and then that this node is at work, so the
        // master tells a slow frame (settling, loading, see-through ensembles) from a hung node.
        link.working(graph.frameNumber());
        // A tile's view, or a foveal inset's rectangle where the scene places it; a node of both
        // eyes draws each in turn and copies it into its half of `pair`.
        const bool both = slot.eye == render::kBothEyes;
        render::Image image;
        for (const int eye : both ? std::vector<int>{-1, 1} : std::vector<int>{0}) {
          const render::WallSlot drawn = drawnSlot(eye);
          const render::ViewSetup view = slotView(drawn);
          // Settled frames (screenshots, deterministic scripted runs) wait for every chunk of the
          // cut, so their pixels are exactly what tessera-render --mosaic makes.
          if (read_back || setup.settled()) {
            image = renderer->renderSettled(instances, view, options, &rs, overlay.drawn());
            if (projector) {
              // The projector's picture is what the tile shows and what the master recomposes.
              projector->run(renderer->imageBuffer());
              if (read_back) image = projector->read();
            }
            // Foveal insets: the context black under them and both cross-faded over the band
            // (render/inset.h), shown and read back alike.
            if (inset_pass) {
              inset_pass->run(renderer->imageBuffer(), setup.wall(), drawn,
                              graph.settings().inset());
              if (read_back) image = inset_pass->read();
            }
          } else {
            renderer->draw(instances, view, options, &rs, overlay.drawn());
            if (projector) projector->run(renderer->imageBuffer());
            if (inset_pass)
              inset_pass->run(renderer->imageBuffer(), setup.wall(), drawn,
                              graph.settings().inset());
          }
          if (both)
            render::copyEyeIntoPair(shownBuffer(), pair.name(), view.width, view.height, eye);
        }
        if (both && read_back)
          image = render::readImageBuffer(pair, tile->pixel_width(), tile->pixel_height());
        if (read_back) r.set_rgba(image.rgba.data(), image.rgba.size());
        cluster::NodeFrameStats& st = *r.mutable_stats();
        st.set_render_ms(msSince(start_time));
        st.set_points(rs.points);
        st.set_nodes(rs.nodes);
        st.set_frames(uint32_t(rs.frames));
        st.set_resident_bytes(rs.stream.resident_bytes);
        st.set_resident_disk_bytes(rs.stream.resident_disk_bytes);
        st.set_chunks_queued(rs.stream.queued);
        st.set_store_bytes(models.storeBytes());
        st.set_barrier_ms(barrier_ms);
        st.set_present_ms(present_ms);
        st.set_relative_depth_lo(rs.relative_depth_range.x);
        st.set_relative_depth_hi(rs.relative_depth_range.y);
      } catch (const std::exception& e) {
        fail(cluster::NODE_RENDER, std::string("rendering: ") + e.what());
        r.clear_rgba();
      }
    }
    *r.mutable_status() = status;
    link.report(r);
    reported = r.frame();
    reported_at = Clock::now();
  }

  /// The last drawn view's picture as shown: after the projector's or the insets' pass.
  uint32_t shownBuffer() const {
    return projector    ? projector->imageBuffer()
           : inset_pass ? inset_pass->imageBuffer()
                        : renderer->imageBuffer();
  }

  void present() {
    barrier_ms = msSince(reported_at);
    present_ms = 0;
    if (!window || status.code() != cluster::NODE_OK) return;
    const auto start_time = Clock::now();
    window->present(pair ? pair.name() : shownBuffer(), tile->pixel_width(), tile->pixel_height());
    window->poll();  // keep the window responsive; input belongs to the master's console
    present_ms = msSince(start_time);
  }

  enum class SessionEnd { kQuit, kDropped };

  /// Frames until the master quits or drops this node. Throws MasterLost.
  SessionEnd frames(int& exit_code) {
    bool todo = false;       // a frame applied and not rendered yet
    bool read_back = false;  // ... and the pixels are asked for
    while (true) {
      // A node behind applies every waiting frame and renders only the newest.
      if (todo && !link.pending()) {
        renderAndReport(read_back);
        todo = read_back = false;
        continue;
      }
      cluster::ToNode m;
      if (!link.receive(m, todo ? Clock::now() : after(opt.master_timeout_s))) {
        if (todo) continue;
        throw sync::MasterLost("no message from the master for " +
                               std::to_string(int(opt.master_timeout_s)) + " s");
      }
      switch (m.kind_case()) {
        case cluster::ToNode::kFrame:
          apply(m.frame());
          todo = true;
          read_back |= m.frame().read_back();
          break;
        case cluster::ToNode::kPresent:
          if (m.present().frame() == reported) present();
          break;
        case cluster::ToNode::kDropped:
          std::fprintf(stderr, "%s: dropped by the master: %s\n", who.c_str(),
                       m.dropped().reason().c_str());
          if (status.code() != cluster::NODE_OK) {
            exit_code = status.code();
            return SessionEnd::kQuit;
          }
          return SessionEnd::kDropped;
        case cluster::ToNode::kQuit:
          exit_code = status.code();
          sayVideoStats();
          return SessionEnd::kQuit;
        default:  // a welcome or refusal out of turn: not for this join
          break;
      }
    }
  }

  int run() {
    struct sigaction sa = {};
    sa.sa_handler = onContinue;
    sa.sa_flags = SA_RESTART;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGCONT, &sa, nullptr);
    cluster::Hello hello;
    hello.set_protocol(sync::kProtocolVersion);
    hello.set_tile(opt.tile);
    hello.set_host(hostName());
    hello.set_pid(uint32_t(getpid()));
    double join_wait = opt.join_timeout_s;
    while (true) {
      cluster::ClusterSetup s;
      try {
        s = link.join(hello, after(join_wait));
      } catch (const sync::JoinRefused& e) {
        std::fprintf(stderr, "%s: the master refused this node: %s\n", who.c_str(), e.what());
        return cluster::NODE_REFUSED;
      } catch (const sync::MasterLost& e) {
        if (gContinued) {  // the connection died while this node was stopped: a new one
          gContinued = 0;
          std::fprintf(stderr, "%s: %s after this node was stopped; joining again\n", who.c_str(),
                       e.what());
          continue;
        }
        std::fprintf(stderr, "%s: %s\n", who.c_str(), e.what());
        return cluster::NODE_MASTER_LOST;
      }
      gContinued = 0;  // a stop before this welcome is behind the node now
      status = cluster::NodeStatus();
      try {
        start(std::move(s));
      } catch (const NodeError& e) {
        fail(e.failure, e.what());
      } catch (const std::exception& e) {
        fail(cluster::NODE_INTERNAL, e.what());
      }
      // The startup report: frame 0, whether this node can render.
      cluster::NodeReport startup;
      *startup.mutable_status() = status;
      link.report(startup);
      reported = 0;
      int exit_code = 0;
      try {
        if (frames(exit_code) == SessionEnd::kQuit) return exit_code;
        hello.set_tile(tile ? tile->name() : opt.tile);  // come back to the same tile
        join_wait = opt.join_timeout_s;
        std::fprintf(stderr, "%s: joining again\n", who.c_str());
      } catch (const sync::MasterLost& e) {
        hello.set_tile(tile ? tile->name() : opt.tile);
        if (gContinued) {
          gContinued = 0;
          std::fprintf(stderr, "%s: %s after this node was stopped; joining again\n", who.c_str(),
                       e.what());
          join_wait = opt.join_timeout_s;
          continue;
        }
        if (opt.wait_master_s <= 0) {
          std::fprintf(stderr, "%s: %s; exiting\n", who.c_str(), e.what());
          return cluster::NODE_MASTER_LOST;
        }
        std::fprintf(stderr, "%s: %s; waiting up to %.0f s for a master\n", who.c_str(), e.what(),
                     opt.wait_master_s);
        join_wait = opt.wait_master_s;
      }
    }
  }
};

RenderNode::RenderNode(sync::NodeLink& link, NodeOptions options)
    : m(std::make_unique<Impl>(link, std::move(options))) {}

RenderNode::~RenderNode() = default;

int RenderNode::run() {
  return m->run();
}

}  // namespace tessera::render_node
