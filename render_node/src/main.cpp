// tessera-node: one render node of the wall (DESIGN.md, render_node/). Started by mpirun after
// the master (MPMD):
//   mpirun -np 1 tessera-master --wall W.json --scene S.json ... : -np K tessera-node [--headless]
// Receives the wall, its tile and a snapshot of the scene from the master; then per frame applies
// the frame to its replica, renders its tile's off-axis view, waits at the swap barrier, presents,
// and sends its statistics (and its pixels on screenshot frames) back. A node that cannot start
// or goes wrong says why to the master (an error code and text) instead of dying silently.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>

#include <tessera/cluster.pb.h>
#include <tessera/core/stopwatch.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/view_renderer.h>
#include <tessera/render/window.h>
#include <tessera/render_node/scene_models.h>
#include <tessera/sync/mpi_transport.h>
#include <tessera/sync/scene_graph.h>
#include <tessera/sync/wire.h>

namespace {

using namespace tessera;
using Clock = std::chrono::steady_clock;
using sync::NodeFailure;

/// A failure with the code the master reports.
struct NodeError : std::runtime_error {
  NodeError(NodeFailure f, const std::string& what) : std::runtime_error(what), failure(f) {}
  NodeFailure failure;
};

/// Everything one node holds while it runs.
class RenderNode {
 public:
  RenderNode(sync::MpiTransport& mpi, bool headless) : mMpi(mpi), mHeadless(headless) {}

  /// Takes the setup: tile, GL context (window or headless), replica, stores, renderer.
  void start(const std::string& setup_bytes) {
    if (!mSetup.ParseFromString(setup_bytes))
      throw NodeError(NodeFailure::kBadFrame, "the master's setup message does not parse");
    const int index = mMpi.rank() - 1;
    if (index < 0 || index >= mSetup.tile_of_node_size() ||
        mSetup.tile_of_node(index) >= uint32_t(mSetup.wall().tiles_size()))
      throw NodeError(NodeFailure::kBadTile,
                      "no tile of the wall for rank " + std::to_string(mMpi.rank()));
    mTile = &mSetup.wall().tiles(int(mSetup.tile_of_node(index)));
    if (mTile->pixel_width() == 0 || mTile->pixel_height() == 0 || mTile->pixel_width() > 16384 ||
        mTile->pixel_height() > 16384)
      throw NodeError(NodeFailure::kBadTile, "tile " + mTile->name() + " is " +
                                                 std::to_string(mTile->pixel_width()) + "x" +
                                                 std::to_string(mTile->pixel_height()) +
                                                 " pixels (1..16384 each way)");
    try {
      if (!mHeadless) {
        try {
          mWindow = render::Window::open(mTile->pixel_width(), mTile->pixel_height(),
                                         "tessera-node " + mTile->name());
        } catch (const render::RenderError& e) {
          std::fprintf(stderr, "tessera-node (rank %d): %s; rendering headless\n", mMpi.rank(),
                       e.what());
        }
      }
      if (!mWindow) mContext = render::GlContext::createHeadless();
    } catch (const render::RenderError& e) {
      throw NodeError(NodeFailure::kNoGl, e.what());
    }
    try {
      mGraph.apply(mSetup.snapshot());
    } catch (const sync::SyncError& e) {
      throw NodeError(NodeFailure::kBadFrame, e.what());
    }
    updateModels();
    render::StreamerOptions stream;
    if (mSetup.gpu_budget_bytes() > 0) stream.budget_bytes = mSetup.gpu_budget_bytes();
    stream.density_ratios = true;  // any model may turn see-through during the session
    try {
      mRenderer = std::make_unique<render::ViewRenderer>(mTile->pixel_width(),
                                                         mTile->pixel_height(), nullptr, stream);
    } catch (const render::RenderError& e) {
      throw NodeError(NodeFailure::kNoGl, e.what());
    }
  }

  /// One frame up to the swap barrier. Returns the tile's pixels when the frame asks for a
  /// screenshot.
  std::optional<render::Image> render(const std::string& frame_bytes, bool screenshot,
                                      sync::NodeFrameStats& st) {
    const auto start = Clock::now();
    try {
      mGraph.apply(sync::parseFrame(frame_bytes));
    } catch (const sync::SyncError& e) {
      throw NodeError(NodeFailure::kBadFrame, e.what());
    }
    updateModels();
    const render::ViewSetup view = render::tileView(mSetup.wall(), *mTile, mGraph.camera());
    const render::RenderOptions options = render_node::SceneModels::options(
        mGraph, mSetup.splat_scale() > 0 ? mSetup.splat_scale() : 2.0f);
    render::RenderStats rs;
    std::optional<render::Image> image;
    try {
      // Settled frames (screenshots, deterministic scripted runs) wait for every chunk of the
      // cut, so their pixels are exactly what tessera-render --mosaic makes.
      if (screenshot || mSetup.settled())
        image = mRenderer->renderSettled(mInstances, view, options, &rs);
      else
        mRenderer->draw(mInstances, view, options, &rs);
    } catch (const std::exception& e) {
      throw NodeError(NodeFailure::kRender, std::string("rendering: ") + e.what());
    }
    if (!screenshot) image.reset();
    st.render_ms = msSince(start);
    st.points = rs.points;
    st.nodes = rs.nodes;
    st.frames = uint32_t(rs.frames);
    st.resident_bytes = rs.stream.resident_bytes;
    st.resident_disk_bytes = rs.stream.resident_disk_bytes;
    st.chunks_queued = rs.stream.queued;
    st.store_bytes = mModels.storeBytes();
    return image;
  }

  /// After the swap barrier: shows the frame (windowed nodes).
  double present() {
    if (!mWindow) return 0.0;
    const auto start = Clock::now();
    mWindow->present(mRenderer->imageBuffer(), mTile->pixel_width(), mTile->pixel_height());
    mWindow->poll();  // keep the window responsive; input belongs to the master's console
    return msSince(start);
  }

 private:
  void updateModels() {
    try {
      mInstances = mModels.update(mGraph);
    } catch (const lod::StoreError& e) {
      throw NodeError(NodeFailure::kBadStore, e.what());
    }
  }

  sync::MpiTransport& mMpi;
  bool mHeadless;
  cluster::ClusterSetup mSetup;
  const config::Tile* mTile = nullptr;
  std::unique_ptr<render::Window> mWindow;
  std::unique_ptr<render::GlContext> mContext;
  sync::SceneGraph mGraph;
  render_node::SceneModels mModels;
  std::vector<render::ModelInstance> mInstances;
  std::unique_ptr<render::ViewRenderer> mRenderer;  // destroyed first: needs the context
};

/// The whole protocol (mpi_transport.h); returns the exit code.
int run(sync::MpiTransport& mpi, bool headless) {
  mpi.gatherHosts();
  sync::ClusterMessage kind{};
  uint32_t flags = 0;
  std::string bytes;
  mpi.broadcast(kind, flags, bytes, "setup from the master");
  if (kind == sync::ClusterMessage::kQuit) return 0;  // the master refused to start
  if (kind != sync::ClusterMessage::kSetup)
    mpi.abort(5, "expected the setup message, got message kind " + std::to_string(int(kind)));

  RenderNode node(mpi, headless);
  sync::NodeStatus status;
  try {
    node.start(bytes);
  } catch (const NodeError& e) {
    status.set(e.failure, e.what());
  } catch (const std::exception& e) {
    status.set(NodeFailure::kInternal, e.what());
  }
  mpi.gatherStatus(status);
  const int failed = status.code;

  while (true) {
    mpi.broadcast(kind, flags, bytes, "frame from the master");
    const bool screenshot = flags & sync::kFrameScreenshot;
    if (kind == sync::ClusterMessage::kQuit) return failed;
    if (kind == sync::ClusterMessage::kFailed) {
      mpi.gatherStatus(status);
      return status.code;
    }
    if (kind != sync::ClusterMessage::kFrame)
      mpi.abort(5, "unexpected message kind " + std::to_string(int(kind)));
    sync::NodeFrameStats st;
    std::optional<render::Image> image;
    if (status.code == 0) {
      try {
        image = node.render(bytes, screenshot, st);
      } catch (const NodeError& e) {
        status.set(e.failure, e.what());
      } catch (const std::exception& e) {
        status.set(NodeFailure::kInternal, e.what());
      }
    }
    st.failure = status.code;
    st.barrier_ms = mpi.swapBarrier();
    if (status.code == 0) st.present_ms = node.present();
    // Every node joins the gather on screenshot frames; one without pixels sends none.
    if (screenshot) {
      mpi.gatherBytes(image ? std::string_view(reinterpret_cast<const char*>(image->rgba.data()),
                                               image->rgba.size())
                            : std::string_view());
    }
    mpi.gatherStats(st);
  }
}

}  // namespace

int main(int argc, char** argv) {
  bool headless = false;
  double timeout_s = 120.0;
  CLI::App app{"tessera-node: one render node of the wall, started by mpirun after tessera-master"};
  app.add_flag("--headless", headless, "Render off-screen (EGL) instead of in a window");
  app.add_option("--timeout", timeout_s,
                 "Seconds to wait for the master at any step before aborting the job")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  // MPI may add its own arguments; ours are parsed after MPI_Init removed them.
  std::unique_ptr<sync::MpiTransport> mpi;
  try {
    mpi = std::make_unique<sync::MpiTransport>(&argc, &argv, "tessera-node", timeout_s);
  } catch (const sync::TransportError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (mpi->rank() == 0) return app.exit(e);
    mpi->abort(2, std::string("bad command line: ") + e.what());
  }
  mpi->setTimeout(timeout_s);
  if (mpi->rank() == 0) {
    mpi->abort(2,
               "tessera-node is rank 0, where tessera-master belongs: start "
               "`mpirun -np 1 tessera-master ... : -np K tessera-node`");
  }
  return run(*mpi, headless);
}
