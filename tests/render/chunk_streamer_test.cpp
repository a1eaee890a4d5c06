// The chunk streamer's loader pool (render/chunk_streamer.h): several loader threads settle to
// the same pixels as one, forget() waits for every item of a store in flight on any of them,
// and the see-through measurements are taken only for chunks drawn see-through, also when a
// model turns see-through after it was drawn opaque; chunks in flight that no frame wants any
// more are given up, and forget() gives up a store's stalled reads. Built and run under
// AddressSanitizer too (scripts/test.sh), where a loader thread decoding into a closed store is
// a use-after-free.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include <glm/gtc/matrix_transform.hpp>

#include <tessera/render/view_renderer.h>

#include "../support/bunny_store_test.h"

namespace tessera::render {
namespace {

class ChunkStreamerTest : public test::BunnyStoreTest {
 protected:
  static std::unique_ptr<lod::PointStore> open() { return lod::PointStore::open(*sDir / "b.tlod"); }
  /// The whole bunny, 320 x 240, from the front.
  static ViewSetup view(const lod::PointStore& s) {
    const auto& sum = s.summary();
    const glm::dvec3 c = sum.origin + 0.5 * (sum.bbox_min + sum.bbox_max);
    ViewSetup v;
    v.eye_world = c + glm::dvec3(0.03, 0.02, 0.3);
    v.view = glm::lookAt(v.eye_world, c, glm::dvec3(0, 1, 0));
    v.projection = glm::perspective(glm::radians(40.0), 320.0 / 240.0, 0.01, 10.0);
    v.width = 320;
    v.height = 240;
    return v;
  }
  static RenderOptions fullResolution() {
    RenderOptions o;
    o.lod_pixels = 0.25;  // every leaf of the small bunny
    o.edl.strength = 1.0f;
    return o;
  }
  static RenderOptions seeThrough() {
    RenderOptions o = fullResolution();
    o.spbr.lod_scale = 0.5;
    o.spbr.ensembles = 4;
    o.spbr.progressive_max = 4;
    return o;
  }
  /// Normals and density ratios too, as see-through views with slant shading off take them.
  static StreamerOptions measuring(uint32_t threads) {
    StreamerOptions so;
    so.loader_threads = threads;
    so.normals = true;
    so.density_ratios = true;
    return so;
  }
};

TEST_F(ChunkStreamerTest, APoolSettlesToTheSameImageAsOneThread) {
  auto s = open();
  ModelInstance opaque{s.get(), storeModel(*s)};
  ModelInstance half = opaque;
  half.opacity = 0.5f;
  const ViewSetup v = view(*s);
  Image one, one_see_through;
  {
    ViewRenderer r(v.width, v.height, nullptr, measuring(1));
    EXPECT_EQ(r.streamer().loaderThreads(), 1u);
    one = r.renderSettled({&opaque, 1}, v, fullResolution());
    // Turning see-through: every chunk loaded again, measured.
    one_see_through = r.renderSettled({&half, 1}, v, seeThrough());
  }
  for (uint32_t threads : {2u, 4u}) {
    SCOPED_TRACE(threads);
    ViewRenderer r(v.width, v.height, nullptr, measuring(threads));
    EXPECT_EQ(r.streamer().loaderThreads(), threads);
    const Image pool = r.renderSettled({&opaque, 1}, v, fullResolution());
    EXPECT_TRUE(pool.rgba == one.rgba);
  }
  // Cold, see-through from the first frame: every chunk measured on one of four threads, and
  // the same pixels as the chunks measured when the model turned see-through.
  ViewRenderer cold(v.width, v.height, nullptr, measuring(4));
  EXPECT_TRUE(cold.renderSettled({&half, 1}, v, seeThrough()).rgba == one_see_through.rgba);
  // 0: one loader thread a core.
  ViewRenderer cores(v.width, v.height);
  EXPECT_EQ(cores.streamer().loaderThreads(), std::max(1u, std::thread::hardware_concurrency()));
}

TEST_F(ChunkStreamerTest, ForgetWaitsForEveryItemOfTheStoreInFlight) {
  // Two stores of the same file: the same nodes at the same distances, so the queue takes
  // them in turn and the four loader threads hold items of both. Every chunk measured, so that
  // an item keeps its thread busy (opaque views: cheap to draw).
  auto a = open();
  auto b = open();
  ModelInstance both[] = {{a.get(), storeModel(*a)}, {b.get(), storeModel(*b)}};
  const ViewSetup v = view(*a);
  const RenderOptions options = fullResolution();
  StreamerOptions so = measuring(4);
  so.measure_every_chunk = true;
  ViewRenderer r(v.width, v.height, nullptr, so);
  r.streamer().pauseLoader(true);
  r.draw(both, v, options);  // queues both cuts' chunks (and pages), coarse first
  ASSERT_GT(r.streamer().stats().queued, 8u);
  r.streamer().pauseLoader(false);
  // Not a timing: the state is reached on any machine, the bound only ends a broken run.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (r.streamer().inFlight() < 2 && std::chrono::steady_clock::now() < give_up)
    std::this_thread::yield();
  ASSERT_GE(r.streamer().inFlight(), 2u);

  r.streamer().forget(*a);
  const auto none_of_a = [&] {
    for (lod::NodeId id = 0; id < a->loadedNodes(); ++id)
      if (r.streamer().find(*a, id)) return false;
    return true;
  };
  EXPECT_TRUE(none_of_a());
  r.streamer().waitForLoader();
  r.streamer().beginFrame();  // uploads what the loader threads finished: nothing of `a`
  EXPECT_TRUE(none_of_a());
  r.streamer().endFrame();
  a.reset();  // closed: a loader thread still reading it would be a use-after-free

  // The other store streams on undisturbed and settles to what it shows alone.
  const Image after = r.renderSettled({&both[1], 1}, v, options);
  ViewRenderer alone(v.width, v.height, nullptr, so);
  const Image expected = alone.renderSettled({&both[1], 1}, v, options);
  EXPECT_TRUE(after.rgba == expected.rgba);
  EXPECT_EQ(r.streamer().stats().resident_bytes, alone.streamer().stats().resident_bytes);
}

/// The store's file through a link that stops answering while `stalled`: every read then
/// waits until its reader gives it up (its cancel token, range_source.h) or the link answers
/// again. A stand-in for a chunk server whose queue holds the site's requests.
class StalledLink final : public lod::RangeSource {
 public:
  explicit StalledLink(const std::filesystem::path& path) : mFile(path) {}
  uint64_t size() const override { return mFile.size(); }
  std::string name() const override { return mFile.name(); }
  void stall(bool on) {
    {
      std::lock_guard lock(mMutex);
      mStalled = on;
    }
    mAnswer.notify_all();
  }
  mutable std::atomic<int> given_up{0};

 private:
  void readRange(uint64_t offset, void* dst, size_t n, std::stop_token cancel) const override {
    {
      std::unique_lock lock(mMutex);
      std::condition_variable_any& answer = mAnswer;
      if (!answer.wait(lock, cancel, [&] { return !mStalled; })) {
        ++given_up;
        throw lod::ReadCancelled("given up");
      }
    }
    mFile.read(offset, dst, n);
  }
  lod::FileRangeSource mFile;
  mutable std::mutex mMutex;
  mutable std::condition_variable_any mAnswer;
  bool mStalled = false;
};

TEST_F(ChunkStreamerTest, ChunksInFlightThatNoFrameWantsAreGivenUpAndAskedForAgainLater) {
  auto link = std::make_unique<StalledLink>(*sDir / "b.tlod");
  StalledLink& stalled = *link;
  auto s = lod::PointStore::open(std::move(link));
  ModelInstance inst{s.get(), storeModel(*s)};
  const ViewSetup v = view(*s);
  const RenderOptions options = fullResolution();
  StreamerOptions so = measuring(2);
  ASSERT_EQ(so.cancel_after_frames, 2u);
  ViewRenderer r(v.width, v.height, nullptr, so);
  stalled.stall(true);
  r.draw({&inst, 1}, v, options);  // the loader threads take the root and wait on the link
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (r.streamer().inFlight() < 1 && std::chrono::steady_clock::now() < give_up)
    std::this_thread::yield();
  ASSERT_GE(r.streamer().inFlight(), 1u);
  const uint32_t waiting = r.streamer().inFlight();

  // The view moves on to nothing of the model: one frame that does not want the chunks keeps
  // them (a chunk at the cut's edge may come back), the second gives them up.
  r.draw({}, v, options);
  EXPECT_EQ(r.streamer().inFlight(), waiting);
  EXPECT_EQ(stalled.given_up.load(), 0);
  r.draw({}, v, options);
  while (r.streamer().inFlight() > 0 && std::chrono::steady_clock::now() < give_up)
    std::this_thread::yield();
  EXPECT_EQ(r.streamer().inFlight(), 0u) << "the stalled reads were given up";
  EXPECT_EQ(stalled.given_up.load(), int(waiting));
  r.draw({}, v, options);
  EXPECT_EQ(r.streamer().stats().cancelled, waiting);
  EXPECT_EQ(r.streamer().stats().failed, 0u) << "given up is not broken";
  EXPECT_FALSE(r.streamer().failed(*s, s->root()));

  // Wanted again once the link answers: the same pixels as a store read from its file.
  stalled.stall(false);
  const Image back = r.renderSettled({&inst, 1}, v, options);
  auto plain = open();
  ModelInstance plain_inst{plain.get(), storeModel(*plain)};
  ViewRenderer fresh(v.width, v.height, nullptr, so);
  EXPECT_TRUE(back.rgba == fresh.renderSettled({&plain_inst, 1}, v, options).rgba);

  // forget() gives a store's stalled reads up instead of waiting for a link that may never
  // answer; the store can then be closed.
  auto other_link = std::make_unique<StalledLink>(*sDir / "b.tlod");
  StalledLink& other_stalled = *other_link;
  auto other = lod::PointStore::open(std::move(other_link));
  ModelInstance other_inst{other.get(), storeModel(*other)};
  other_stalled.stall(true);
  r.draw({&other_inst, 1}, v, options);
  while (r.streamer().inFlight() < 1 && std::chrono::steady_clock::now() < give_up)
    std::this_thread::yield();
  ASSERT_GE(r.streamer().inFlight(), 1u);
  r.streamer().forget(*other);
  EXPECT_EQ(r.streamer().inFlight(), 0u);
  EXPECT_GE(other_stalled.given_up.load(), 1);
  other.reset();
}

TEST_F(ChunkStreamerTest, OnlyChunksDrawnSeeThroughAreMeasured) {
  auto s = open();
  ModelInstance inst{s.get(), storeModel(*s)};
  const ViewSetup v = view(*s);
  CutOptions co;
  co.pixel_threshold = fullResolution().lod_pixels;
  const Cut cut = selectCut(*s, inst.model, v, co);
  ASSERT_GT(cut.nodes.size(), 4u);
  co.pixel_threshold *= seeThrough().spbr.lod_scale;  // see-through views refine further
  const Cut see_cut = selectCut(*s, inst.model, v, co);

  ViewRenderer r(v.width, v.height, nullptr, measuring(2));
  const Image opaque = r.renderSettled({&inst, 1}, v, fullResolution());
  for (const CutNode& n : cut.nodes) {
    const GpuChunk* c = r.streamer().find(*s, n.id);
    ASSERT_NE(c, nullptr);
    EXPECT_FALSE(c->measured);
    EXPECT_EQ(c->density, 0.0);
    EXPECT_EQ(c->density_ratios.name(), 0u);
    EXPECT_EQ(r.streamer().find(*s, n.id, ChunkUse::kSeeThrough), nullptr);
  }

  // The model turns see-through: its chunks are loaded again with their measurements (the
  // pixels are those of a streamer that measured from the start: the test above).
  inst.opacity = 0.5f;
  r.renderSettled({&inst, 1}, v, seeThrough());
  size_t dense = 0;  // a chunk of a handful of points has no density (0)
  for (const CutNode& n : see_cut.nodes) {
    const GpuChunk* c = r.streamer().find(*s, n.id, ChunkUse::kSeeThrough);
    ASSERT_NE(c, nullptr);
    EXPECT_TRUE(c->measured);
    EXPECT_NE(c->density_ratios.name(), 0u);
    dense += c->density > 0.0;
  }
  EXPECT_GT(dense, see_cut.nodes.size() / 2);

  // Opaque again: the measured chunks serve as they are.
  inst.opacity = 1.0f;
  RenderStats st;
  EXPECT_TRUE(r.renderSettled({&inst, 1}, v, fullResolution(), &st).rgba == opaque.rgba);
  EXPECT_EQ(st.frames, 1u);

  // The loader can measure every chunk: the baseline of bench/loader_pool.
  StreamerOptions every = measuring(2);
  every.measure_every_chunk = true;
  ViewRenderer all(v.width, v.height, nullptr, every);
  EXPECT_TRUE(all.renderSettled({&inst, 1}, v, fullResolution()).rgba == opaque.rgba);
  for (const CutNode& n : cut.nodes) EXPECT_TRUE(all.streamer().find(*s, n.id)->measured);
}

}  // namespace
}  // namespace tessera::render
