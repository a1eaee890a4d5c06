#include <tessera/collab/site_session.h>

#include <google/protobuf/util/json_util.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <tuple>
#include <type_traits>

#include <imgui.h>
#include <glm/gtc/matrix_transform.hpp>

#include <tessera/collab/chunk_client.h>
#include <tessera/collab/site_messages.h>
#include <tessera/media/video_packet.h>
#include <tessera/media/video_source.h>
#include <tessera/media/voice_alsa.h>
#include <tessera/media/voice_bridge.h>
#include <tessera/media/voice_wav.h>
#include <tessera/core/file_checks.h>
#include <tessera/interact/console_notes.h>
#include <tessera/interact/keys.h>
#include <tessera/interact/measure_tool.h>
#include <tessera/interact/one_button_navigation.h>
#include <tessera/interact/surface_pick.h>
#include <tessera/render/gl_context.h>
#include <tessera/render/scene_draw_list.h>
#include <tessera/render/scene_overlay.h>
#include <tessera/render/video_textures.h>
#include <tessera/render/view_renderer.h>
#include <tessera/render/window.h>
#include <tessera/sync/camera_state.h>
#include <tessera/sync/config.h>
#include <tessera/sync/vec3.h>
#include <tessera/sync/view.h>

namespace tessera::collab {

namespace {

/// The keys a site's window offers (interact/keys.h), as its title lists them.
constexpr interact::Command kSiteKeys[] = {
    interact::Command::kLead,       interact::Command::kRelease, interact::Command::kFollow,
    interact::Command::kUndoSketch, interact::Command::kClearSketches,
    interact::Command::kAddNote,    interact::Command::kMeasure, interact::Command::kLasso,
    interact::Command::kSnap,       interact::Command::kOpenNote, interact::Command::kPicture};

namespace fs = std::filesystem;
using sync::vec;
using Clock = std::chrono::steady_clock;
using Why = SiteSessionEnded::Why;

[[noreturn]] void fail(const std::string& file, const std::string& field, const std::string& what) {
  throw sync::ConfigError("collab::loadSiteScript(): " + file + ": " +
                          (field.empty() ? "" : field + ": ") + what);
}


/// The camera every process of the session would decode from it (the wire's rounding), so a
/// leader and its followers render the very same view.
config::Camera asSent(const config::Camera& c) {
  return sync::decodeCamera(sync::encodeCamera(c));
}

}  // namespace

/// The script's defaults where it is silent: 30 frames a second, 640x480, 45 degrees.
static void withDefaults(site::SiteScript& s) {
  if (s.fps() == 0) s.set_fps(30);
  if (s.width() == 0) s.set_width(640);
  if (s.height() == 0) s.set_height(480);
  if (s.fovy_deg() == 0) s.set_fovy_deg(45);
}

site::SiteScript loadSiteScript(const std::string& path) {
  if (const auto why = notRegularFile(path)) fail(path, "", "cannot open: " + *why);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "", "cannot open");
  std::ostringstream text;
  text << in.rdbuf();
  site::SiteScript s;
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = false;
  const auto status = google::protobuf::util::JsonStringToMessage(text.str(), &s, options);
  if (!status.ok()) fail(path, "", "not a valid SiteScript: " + std::string(status.message()));
  withDefaults(s);
  if (!(s.fps() > 0 && s.fps() <= 240)) fail(path, "fps", "must be in (0, 240]");
  if (s.width() < 16 || s.width() > 8192 || s.height() < 16 || s.height() > 8192)
    fail(path, "width/height", "16..8192 pixels each");
  if (!(s.fovy_deg() > 0 && s.fovy_deg() < 180)) fail(path, "fovyDeg", "must be in (0, 180)");
  uint32_t previous = 0;
  for (int i = 0; i < s.actions_size(); ++i) {
    const site::SiteAction& a = s.actions(i);
    const std::string field = "actions[" + std::to_string(i) + "]";
    if (a.frame() < previous) fail(path, field + ".frame", "actions must be in frame order");
    previous = a.frame();
    switch (a.action_case()) {
      case site::SiteAction::kCamera:
        if (auto why = sync::viewProblem(a.camera()))
          fail(path, field + (why->on_up ? ".camera.up" : ".camera"), why->what);
        break;
      case site::SiteAction::kStroke: {
        const site::StrokeAction& st = a.stroke();
        if (st.pixels_size() % 2 != 0 || st.world_size() % 3 != 0)
          fail(path, field + ".stroke", "pixels are x y pairs, world points x y z triples");
        if ((st.pixels_size() > 0) == (st.world_size() > 0))
          fail(path, field + ".stroke", "needs pixels or world points (one of them)");
        const int n = st.pixels_size() / 2 + st.world_size() / 3;
        if (n < 2 || n > kMaxStrokePoints)
          fail(path, field + ".stroke", "needs 2.." + std::to_string(kMaxStrokePoints) + " points");
        for (float v : st.pixels())
          if (!std::isfinite(v)) fail(path, field + ".stroke.pixels", "numbers must be finite");
        for (double v : st.world())
          if (!std::isfinite(v) || std::abs(v) > kMaxCoordinate)
            fail(path, field + ".stroke.world", "numbers must be finite, within 1e8 m");
        for (float v : {st.color().r(), st.color().g(), st.color().b()})
          if (!(v >= 0 && v <= 1)) fail(path, field + ".stroke.color", "components in [0, 1]");
        if (!(st.width() >= 0 && st.width() <= 64))
          fail(path, field + ".stroke.width", "must be in [0, 64] pixels");
        break;
      }
      case site::SiteAction::kNote: {
        const site::NoteAction& n = a.note();
        if (n.pixel_size() != 0 && n.pixel_size() != 2)
          fail(path, field + ".note.pixel", "x y, or none");
        for (float v : n.pixel())
          if (!std::isfinite(v)) fail(path, field + ".note.pixel", "numbers must be finite");
        if (n.note().edit_case() == site::SiteNote::EDIT_NOT_SET)
          fail(path, field + ".note.note", "names no edit (add, update, remove, layer, open)");
        if (n.note().has_add() && n.note().add().place() == 0 && n.pixel_size() == 0 &&
            n.note().add().position_size() != 3)
          fail(path, field + ".note", "a new place needs a pixel or a position");
        break;
      }
      case site::SiteAction::kMeasure: {
        const site::MeasureAction& me = a.measure();
        if (!scene::MeasurementPayload::Type_IsValid(me.type()))
          fail(path, field + ".measure.type", "unknown type");
        if (me.pixels_size() % 2 != 0 || me.pixels_size() / 2 > kMaxMeasurePoints)
          fail(path, field + ".measure.pixels",
               "x y pairs, at most " + std::to_string(kMaxMeasurePoints));
        for (float v : me.pixels())
          if (!std::isfinite(v)) fail(path, field + ".measure.pixels", "numbers must be finite");
        break;
      }
      case site::SiteAction::kLasso: {
        const site::LassoAction& l = a.lasso();
        if (l.pixels_size() % 2 != 0 || l.pixels_size() < 6 ||
            l.pixels_size() > 2 * kMaxLassoPoints)
          fail(path, field + ".lasso.pixels",
               "3.." + std::to_string(kMaxLassoPoints) + " x y pairs");
        for (float v : l.pixels())
          if (!std::isfinite(v)) fail(path, field + ".lasso.pixels", "numbers must be finite");
        break;
      }
      case site::SiteAction::kSnap: {
        const site::SnapAction& sn = a.snap();
        const bool heavy = sn.heavy_width() > 0.0f;
        if (!(sn.heavy_width() >= 0.0f && sn.heavy_width() <= kMaxHeavyStrokeWidth))
          fail(path, field + ".snap.heavy_width",
               "0 or up to " + std::to_string(int(kMaxHeavyStrokeWidth)) + " pixels");
        for (const auto& [px, name, least] :
             {std::tuple{&sn.foreground(), ".snap.foreground", heavy ? 3 : 1},
              {&sn.background(), ".snap.background", heavy ? 0 : 1}}) {
          const int most = heavy && least == 0 ? 0 : kMaxSnapStrokePoints;
          if (px->size() % 2 != 0 || px->size() < 2 * least || px->size() > 2 * most)
            fail(path, field + name,
                 std::to_string(least) + ".." + std::to_string(most) + " x y pairs");
          for (float v : *px)
            if (!std::isfinite(v)) fail(path, field + name, "numbers must be finite");
        }
        break;
      }
      case site::SiteAction::kScreenshot:
        if (a.screenshot().empty() || a.screenshot().find('/') != std::string::npos)
          fail(path, field + ".screenshot", "a file name in the output folder");
        break;
      case site::SiteAction::ACTION_NOT_SET:
        fail(path, field, "names no action");
      default:
        break;
    }
  }
  return s;
}

struct SiteSession::Impl {
  SiteSessionOptions opt;
  const Clock::time_point started = Clock::now();
  site::SiteScript script;
  std::unique_ptr<SiteClient> client;
  std::unique_ptr<ChunkClient> chunks;  // stopped first: loaders waiting on it give up at once
  bool first_image = false, view_settled = false;
  site::SiteWelcome welcome;
  sync::SceneGraph graph;
  std::unique_ptr<render::Window> window;  // --window: the user's view and input
  std::unique_ptr<render::GlContext> context;
  render::SceneDrawList models;
  std::span<const render::ModelInstance> instances;
  std::unique_ptr<render::ViewRenderer> renderer;  // destroyed before the context
  config::Camera own, follow_from;
  bool following = false;
  double follow_start = 0;
  uint64_t sequence = 0;
  std::ofstream strokes_csv;
  uint64_t strokes = 0;
  uint64_t notes_sent = 0, measures_sent = 0, lassos_sent = 0, snaps_sent = 0;
  bool want_pick = false;  // render pick ids (a note's pixel)
  // --window: one-button navigation (left button, wheel), strokes (right-button drag).
  interact::OneButtonNavigation navigation;
  render::ViewSetup last_view;
  std::vector<float> drag;  // the right-button drag's pixels so far
  bool right_held = false;
  // --window tools, as the master's console has them (keys A, M, S, N, O), sent as the script's
  // actions are: a note, measure (clicks), lasso (a left drag), snap (left stroke in, right out).
  interact::ToolKeys tools;
  using Tool = interact::ToolKeys::Tool;
  // A: the next click on the model places a note, then a small form (Dear ImGui) asks its layer,
  // title and text; Add sends it as the script's note action does (SiteNote add).
  std::optional<glm::dvec2> note_pixel;
  char note_layer[256] = "notes", note_title[1025] = "", note_text[2048] = "";
  bool note_focus = false;
  std::vector<float> tool_px, snap_bg;  // x y pairs: the clicks, the lasso or the snap strokes
  glm::dvec2 press_at{0.0};
  Clock::time_point last_input = Clock::now();
  // --audio-in / --audio-out: its microphone and speaker, clocked from the welcome.
  std::unique_ptr<media::VoiceStation> station;
  std::unique_ptr<media::AlsaMicrophone> microphone;  // --audio-in alsa:DEVICE
  std::unique_ptr<media::AlsaSpeaker> speaker;        // --audio-out alsa:DEVICE
  Clock::time_point voice_start = Clock::now();
  // --video: its source and sender, paced by the loop; other sites' insets.
  std::unique_ptr<media::VideoSource> video_source;
  std::unique_ptr<media::VideoSender> video_sender;
  media::VideoPicture video_picture;
  Clock::time_point video_next;
  uint64_t video_frames = 0, video_bytes = 0;
  double video_encode_ms = 0;
  std::unique_ptr<render::VideoTextures> videos;  // before the context goes (~Impl)

  /// Sends a picture from the source if one is due (one at most: pictures missed while the
  /// loop was busy are skipped, not sent in a burst). Called wherever the loop waits or works
  /// in steps (sleeps, settling a screenshot, poses), so a busy site still sends video.
  void pumpVideo() {
    if (!video_sender) return;
    const auto now = Clock::now();
    if (now < video_next) return;
    const auto period = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(1.0 / video_sender->encoder().settings().fps));
    video_next += period;
    if (video_next < now) video_next = now + period;  // late: skip, no burst
    if (!video_source->grab(video_picture)) return;   // a camera without a new picture
    const auto start = Clock::now();
    const auto packets = video_sender->send(video_picture);
    video_encode_ms += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    ++video_frames;
    site::ToMaster m;
    for (const auto& p : packets) {
      video_bytes += p.size();
      m.set_video(p.data(), p.size());
      client->send(m);
    }
  }

  /// Sleeps until `until`, sending the pictures that fall due meanwhile: video keeps its own
  /// rate whatever the loop's.
  void sleepSendingVideo(Clock::time_point until) {
    while (video_sender && video_next < until) {
      std::this_thread::sleep_until(video_next);
      pumpVideo();
    }
    std::this_thread::sleep_until(until);
  }

  void sayVideo() {
    if (!video_sender || video_frames == 0) return;
    const double s = std::max(1e-3, elapsed());
    char line[200];
    std::snprintf(line, sizeof line,
                  "video: sent %llu pictures, %llu bytes (%.0f kbit/s), %.2f ms to encode each",
                  (unsigned long long)video_frames, (unsigned long long)video_bytes,
                  double(video_bytes) * 8.0 / 1000.0 / s, video_encode_ms / double(video_frames));
    say(line);
  }

  double voiceNow() const {
    return std::chrono::duration<double>(Clock::now() - voice_start).count();
  }

  /// Sends the microphone's frames that are due and plays the speaker's blocks (every frame).
  void tickVoice() {
    if (!station) return;
    const double now = voiceNow();
    const auto send = [this](std::vector<uint8_t> bytes) {
      site::ToMaster m;
      m.set_voice(bytes.data(), bytes.size());
      client->send(m);
    };
    if (microphone)
      microphone->pump(now, [&](std::span<const float> frame) { station->sendLive(frame, send); });
    station->advance(now, send);
    if (speaker)
      speaker->pump(now, [this](double at, std::span<float> out) { station->playLive(at, out); });
  }

  /// --audio-out: what it heard, written when the session ends however it ends.
  void writeSpeaker() {
    if (!station || opt.audio_out.empty() || speaker) return;
    try {
      media::writeWav(opt.audio_out, station->speaker());
      say("wrote what this site heard to " + opt.audio_out);
    } catch (const media::WavError& e) {
      std::fprintf(stderr, "tessera-site: %s\n", e.what());
    }
  }

  ~Impl() {
    if (chunks) {
      const ChunkClientCounters c = chunks->counters();
      char line[320];
      std::snprintf(line, sizeof line,
                    "chunks: fetched %llu bytes in %llu requests (%llu sent again); %llu ranges "
                    "(%llu bytes) from the cache, %llu cached ranges failed their checksum or "
                    "size and were fetched again; %llu requests withdrawn (the view moved on)",
                    (unsigned long long)c.fetched_bytes, (unsigned long long)c.requests,
                    (unsigned long long)c.retries, (unsigned long long)c.cache_hits,
                    (unsigned long long)c.cache_bytes, (unsigned long long)c.refetched,
                    (unsigned long long)c.cancelled);
      say(line);
      if (c.cache_evicted_files > 0) {
        std::snprintf(line, sizeof line,
                      "chunks: %llu cached ranges (%llu bytes) removed to keep the cache within "
                      "%.1f MB",
                      (unsigned long long)c.cache_evicted_files,
                      (unsigned long long)c.cache_evicted_bytes, opt.cache_mb);
        say(line);
      }
      if (!chunks->cacheProblem().empty())
        say("chunks: the disk cache is not complete: " + chunks->cacheProblem());
      chunks.reset();
    }
    if (renderer) {  // the window's or the headless context is current
      render::ChunkStreamer* s[] = {&renderer->streamer()};
      models.clear(s);
    }
    if (videos) {
      const render::VideoTextureStats v = videos->stats();
      if (v.packets > 0) {
        char line[200];
        std::snprintf(line, sizeof line,
                      "video from other sites: %llu packets, %llu pictures decoded, %llu errors",
                      (unsigned long long)v.packets, (unsigned long long)v.decoded,
                      (unsigned long long)v.errors);
        say(line);
      }
    }
    videos.reset();
    renderer.reset();
  }

  void say(const std::string& text) {
    std::printf("tessera-site %s: %s\n",
                welcome.name().empty() ? opt.client.name.c_str() : welcome.name().c_str(),
                text.c_str());
    std::fflush(stdout);
  }

  void update(const sync::SceneChanges& changes) {
    if (!renderer || changes.empty()) return;
    render::ChunkStreamer* s[] = {&renderer->streamer()};
    instances = models.update(graph, changes, s);
  }

  /// A perspective view of `camera` whose depth range holds every model.
  render::ViewSetup view(const config::Camera& camera) const {
    render::ViewSetup v;
    v.view = render::cameraView(camera);
    v.width = script.width();
    v.height = script.height();
    v.eye_world = vec(camera.eye());
    glm::dvec3 lo(1e300), hi(-1e300);
    for (const render::ModelInstance& inst : instances) {
      const auto [a, b] = render::worldBounds(inst);
      lo = glm::min(lo, a);
      hi = glm::max(hi, b);
    }
    double radius = 1.0, dist = glm::length(vec(camera.target()) - vec(camera.eye()));
    if (!instances.empty()) {
      radius = std::max(1e-6, 0.5 * glm::length(hi - lo));
      dist = glm::length(0.5 * (lo + hi) - vec(camera.eye()));
    }
    const double near = std::max(1e-4 * radius, (dist - 2.0 * radius) * 0.5);
    v.projection =
        glm::perspective(glm::radians(double(script.fovy_deg())),
                         double(script.width()) / script.height(), near, dist + 2.0 * radius);
    return v;
  }

  /// Every sketch and avatar but its own and any at its eye (its leader's, when it follows).
  render::Overlay overlay(const config::Camera& c) const {
    render::Overlay o;
    render::SceneOverlayOptions so;
    so.hide_site = welcome.name();
    so.viewer_eye = vec(c.eye());
    so.hide_near_m = 1e-3 * std::max(1e-3, glm::length(vec(c.target()) - vec(c.eye())));
    if (videos) {
      so.video_texture = [this](uint32_t source) { return videos->texture(source); };
      so.screen_wall = so.screen_view = glm::dvec4(0.0, 0.0, script.width(), script.height());
      so.view_px = glm::dvec2(script.width(), script.height());
    }
    render::appendSceneOverlay(graph, o, so);
    if (window) {  // the navigation's bar and target, as the master's console shows them
      const float w = float(script.width()), h = float(script.height());
      const float bar = w * float(1.0 - interact::OneButtonNavigation::kBarFraction);
      o.rects.push_back({{bar, 0.0f}, {w, h}, {255, 255, 255, 64}});
      if (const auto& t = navigation.target()) {
        render::OverlayPoint ring;
        ring.at = *t;
        ring.size_px = 2.0f * float(interact::OneButtonNavigation::kTargetRadiusPx);
        ring.ring_px = 3.0f;
        ring.color = {255, 255, 255, 230};
        o.points.push_back(ring);
      }
      // The stroke being drawn, and the tools' clicks and strokes, on top.
      auto marks = [&](const std::vector<float>& px, glm::u8vec4 color, float r) {
        for (size_t i = 0; i + 1 < px.size(); i += 2)
          o.rects.push_back({{px[i] - r, px[i + 1] - r}, {px[i] + r, px[i + 1] + r}, color});
      };
      marks(drag, {255, 255, 255, 200}, 2.0f);
      marks(tool_px,
            tools.tool() == Tool::kMeasure ? glm::u8vec4{90, 230, 255, 255}
            : tools.tool() == Tool::kLasso ? glm::u8vec4{255, 190, 0, 230}
                                          : glm::u8vec4{60, 230, 90, 230},
            tools.tool() == Tool::kMeasure ? 4.0f : 1.5f);
      marks(snap_bg, {240, 60, 60, 230}, 1.5f);
    }
    return o;
  }

  /// The camera this site shows now.
  config::Camera camera(double now) {
    if (!following) return own;
    const config::Camera target = graph.camera();
    const double s = std::clamp((now - follow_start) / 0.5, 0.0, 1.0);
    own = s >= 1.0 ? target : blendCameras(follow_from, target, s * s * (3.0 - 2.0 * s));
    return own;
  }

  void sendPose(const config::Camera& c) {
    site::ToMaster m;
    site::SitePose& p = *m.mutable_pose();
    p.set_sequence(++sequence);
    auto add = [](google::protobuf::RepeatedField<double>* f, const config::Vec3& v) {
      f->Add(v.x());
      f->Add(v.y());
      f->Add(v.z());
    };
    add(p.mutable_eye(), c.eye());
    add(p.mutable_target(), c.target());
    add(p.mutable_up(), c.up());
    p.set_fovy_deg(script.fovy_deg());
    p.set_aspect(float(double(script.width()) / script.height()));
    client->send(m);
    tickVoice();
    pumpVideo();
  }

  render::RenderOptions options() const {
    render::RenderOptions o = render::SceneDrawList::options(graph, 2.0f);
    o.pick_ids = want_pick;                         // a note placed under a pixel names its model
    o.highlights = render::sceneHighlights(graph);  // selections, as the wall tints them
    return o;
  }

  double elapsed() const { return std::chrono::duration<double>(Clock::now() - started).count(); }

  /// Frames until the whole cut is resident (render::ViewRenderer::renderSettled(), but the
  /// link goes on meanwhile: frames are applied and poses sent while chunks arrive, which over
  /// a slow link may take many seconds).
  render::Image settled(const config::Camera& c) {
    const render::Overlay o = overlay(c);
    const render::RenderOptions ro = options();
    const uint32_t ensembles = std::max(ro.spbr.ensembles, ro.spbr.progressive_max);
    render::RenderStats st;
    render::Image img;
    const auto period = std::chrono::duration<double>(1.0 / script.fps());
    for (size_t frame = 1; frame <= 100000; ++frame) {
      img = renderer->render(instances, view(c), ro, &st, o.empty() ? nullptr : &o);
      noteProgress(st);
      if (st.stream.requested == 0 && st.stream.pages_requested == 0) {
        if (st.ensembles == 0 || st.ensembles >= ensembles) break;
        continue;  // a resting see-through view: more ensembles
      }
      update(client->receive(graph,
                             Clock::now() + std::chrono::duration_cast<Clock::duration>(period)));
      sendPose(c);
    }
    return img;
  }

  /// Opens a store the scene names (a lod::PointStore or lod::MeshStore): from this host, or
  /// from the master's chunk server.
  /// A see-through mesh's points (MESH#points) are on this host when the mesh is: sampled here,
  /// as the master and its nodes do.
  template <class Store>
  std::unique_ptr<Store> openStore(const std::string& path, const char* kind) {
    auto local = [&] {
      if constexpr (std::is_same_v<Store, lod::PointStore>)
        return render::SceneDrawList::openLocalStore(path);
      else
        return Store::open(path);
    };
    const auto mesh = render::SceneDrawList::meshOfPointsKey(path);
    std::error_code ec;
    const bool here = fs::is_regular_file(mesh ? *mesh : path, ec);
    if (!chunks || (here && !opt.remote_stores)) {
      if (here) return local();
      try {
        return local();
      } catch (const std::runtime_error& e) {
        throw lod::StoreError(std::string(e.what()) +
                              " (not on this host, and the master serves no chunks: start it "
                              "with --chunks to stream them)");
      }
    }
    try {
      return Store::open(chunks->open(path));
    } catch (const lod::RangeError& e) {
      throw lod::StoreError(std::string(kind) + ": " + path +
                            ": from the chunk server: " + e.what());
    }
  }

  /// After a frame: when this site first showed data, and when its view first settled (join
  /// time, bench/sites).
  void noteProgress(const render::RenderStats& st) {
    auto note = [&](const char* what) {
      char line[160];
      std::snprintf(line, sizeof line, "%s at %.3f s: %zu chunks drawn, %llu bytes fetched", what,
                    elapsed(), st.nodes,
                    (unsigned long long)(chunks ? chunks->counters().fetched_bytes : 0));
      say(line);
    };
    if (!first_image && st.nodes > 0) {
      first_image = true;
      note("first image");
    }
    if (first_image && !view_settled && st.stream.requested == 0 &&
        st.stream.pages_requested == 0 && st.stream.queued == 0) {
      view_settled = true;
      note("view settled");
    }
  }

  struct Surface {
    glm::dvec3 world;
    uint32_t x = 0, y = 0;  // the pixel
    float z = 1.0f;         // its window depth
  };
  /// The surface under a pixel of the last frame: the median depth of its 3x3 pixels that show
  /// the model, so a sample never falls through a gap between splats onto what lies behind,
  /// nor takes a neighbouring splat that stands in front on a slanted surface. None when most
  /// of them show the background, or the pixel is outside the view.
  static std::optional<Surface> surfaceAt(const std::vector<uint32_t>& depth,
                                          const render::ViewSetup& v, const glm::dmat4& unproject,
                                          glm::dvec2 pixel) {
    if (!(pixel.x >= 0 && pixel.y >= 0 && pixel.x < v.width && pixel.y < v.height))
      return std::nullopt;
    const uint32_t x = uint32_t(pixel.x), y = uint32_t(pixel.y);
    std::vector<uint32_t> around;
    for (uint32_t yy = y > 0 ? y - 1 : 0; yy <= std::min(y + 1, v.height - 1); ++yy)
      for (uint32_t xx = x > 0 ? x - 1 : 0; xx <= std::min(x + 1, v.width - 1); ++xx) {
        const uint32_t dd = depth[size_t(v.height - 1 - yy) * v.width + xx];
        if (dd != render::kEmptyDepth) around.push_back(dd);
      }
    if (around.size() < 5) return std::nullopt;
    std::nth_element(around.begin(), around.begin() + around.size() / 2, around.end());
    const uint32_t d = around[around.size() / 2];  // float bits order like the depths
    float z = 1.0f;
    std::memcpy(&z, &d, 4);
    const glm::dvec4 ndc((x + 0.5) / v.width * 2.0 - 1.0, 1.0 - (y + 0.5) / v.height * 2.0,
                         2.0 * z - 1.0, 1.0);
    const glm::dvec4 w = unproject * ndc;
    return Surface{glm::dvec3(w) / w.w, x, y, z};
  }

  /// A script's note: a new place under a pixel is placed on the surface there (its model
  /// named by the pick ids), a hot spot without a view gets this camera; then it is checked as
  /// the master will check it, and sent.
  void note(const site::NoteAction& a, const config::Camera& c) {
    site::ToMaster m;
    site::SiteNote& n = *m.mutable_note() = a.note();
    const uint64_t index = ++notes_sent;
    if (n.request() == 0) n.set_request(index);
    if (n.has_add() && n.add().place() == 0 && a.pixel_size() == 2) {
      if (!renderer) {
        say("note " + std::to_string(n.request()) + " skipped: pixels need rendering");
        return;
      }
      want_pick = true;
      (void)settled(c);
      want_pick = false;
      const render::ViewSetup v = view(c);
      const glm::dvec2 pixel(a.pixel(0), a.pixel(1));
      const std::optional<Surface> at =
          surfaceAt(renderer->target().readDepth(), v, glm::inverse(v.projection * v.view), pixel);
      if (!at) {
        say("note " + std::to_string(n.request()) + " skipped: no surface under its pixel");
        return;
      }
      site::NoteAdd& add = *n.mutable_add();
      add.clear_position();
      for (int k = 0; k < 3; ++k) add.add_position(at->world[k]);
      if (add.model().empty()) {
        const auto hit = renderer->pick(at->x, at->y);
        const std::vector<uint32_t>& nodes = models.instanceNodes();
        if (hit && hit->model < nodes.size() && graph.contains(nodes[hit->model]))
          add.set_model(graph.node(nodes[hit->model]).name());
      }
    }
    if (n.has_add() && n.add().radius() > 0.0 && n.add().view_size() == 0) {
      for (const config::Vec3& p : {c.eye(), c.target(), c.up()})
        for (double k : {p.x(), p.y(), p.z()}) n.mutable_add()->add_view(k);
      n.mutable_add()->add_view(script.fovy_deg());
    }
    if (const auto why = checkToMaster(m)) {
      say("note " + std::to_string(n.request()) + " not sent: " + *why);
      return;
    }
    say("note " + std::to_string(n.request()) + " sent");
    client->send(m);
  }

  /// A script's measurement: each pixel picked on the full-resolution surface under it (the
  /// stores, or the chunks the master serves), measured here, checked as the master will
  /// check it, and sent.
  void measure(const site::MeasureAction& a, const config::Camera& c) {
    const uint64_t index = ++measures_sent;
    const std::string what = "measurement " + std::to_string(index);
    if (!renderer) {
      say(what + " skipped: picking needs rendering");
      return;
    }
    want_pick = true;
    (void)settled(c);
    want_pick = false;
    const render::ViewSetup v = view(c);
    interact::MeasureTool tool;
    tool.setMode(
        a.type() == scene::MeasurementPayload::DISTANCE   ? interact::MeasureTool::Mode::kDistance
        : a.type() == scene::MeasurementPayload::ANGLE    ? interact::MeasureTool::Mode::kAngle
        : a.type() == scene::MeasurementPayload::POLYLINE ? interact::MeasureTool::Mode::kPath
                                                          : interact::MeasureTool::Mode::kArea);
    std::optional<interact::MeasureTool::Finished> done;
    try {
      for (int i = 0; i + 1 < a.pixels_size() && !done; i += 2) {
        const auto at =
            interact::pickUnderPixel(*renderer, instances, v, {a.pixels(i), a.pixels(i + 1)});
        if (!at) {
          say(what + " skipped: no surface under pixel " + std::to_string(int(a.pixels(i))) + "," +
              std::to_string(int(a.pixels(i + 1))));
          return;
        }
        done = tool.addPoint(*at, instances);
      }
      if (!done) done = tool.complete(instances);
    } catch (const std::exception& e) {  // annotate::MeasureError, a store that cannot be read
      say(what + " failed: " + e.what());
      return;
    }
    if (!done) {
      say(what + " skipped: too few points");
      return;
    }
    site::ToMaster m;
    site::SiteMeasure& me = *m.mutable_measure();
    me.set_type(done->type);
    for (const glm::dvec3& p : done->points)
      for (int k = 0; k < 3; ++k) me.add_points(p[k]);
    me.set_value(done->measured.value);
    me.set_uncertainty(done->measured.uncertainty);
    if (const auto why = checkToMaster(m)) {
      say(what + " not sent: " + *why);
      return;
    }
    say(what + " sent: " + tool.lastLabel());
    client->send(m);
  }

  /// The MODEL node named `name` (the first MODEL node when empty), or 0 (said, as `what`).
  uint32_t modelFor(const std::string& name, const std::string& what) {
    if (!name.empty()) {
      if (const auto id = graph.findByName(name);
          id && graph.node(*id).kind() == scene::SceneNode::MODEL)
        return *id;
    } else {
      for (uint32_t id : graph.ids())
        if (graph.node(id).kind() == scene::SceneNode::MODEL) return id;
    }
    say(what + " skipped: the scene has no model " +
        (name.empty() ? std::string() : "named \"" + name + "\""));
    return 0;
  }

  /// Fills a SiteSelect's or SiteSnap's model and view from this site's view `c`.
  template <class M>
  void setSentView(M& s, uint32_t model, const config::Camera& c) {
    const render::ViewSetup v = view(c);
    s.set_model(model);
    for (int k = 0; k < 16; ++k) {
      s.add_view(v.view[k / 4][k % 4]);
      s.add_projection(v.projection[k / 4][k % 4]);
    }
    s.set_width(v.width);
    s.set_height(v.height);
  }

  /// Checks and sends a selection request.
  void sendChecked(const site::ToMaster& m, const std::string& what) {
    if (const auto why = checkToMaster(m)) {
      say(what + " not sent: " + *why);
      return;
    }
    say(what + " sent");
    client->send(m);
  }

  /// A script's lasso: its pixels and this view go to the master, which selects (SiteSelect).
  void lasso(const site::LassoAction& a, const config::Camera& c) {
    const std::string what = "lasso " + std::to_string(++lassos_sent);
    const uint32_t model = modelFor(a.model(), what);
    if (!model) return;
    site::ToMaster m;
    site::SiteSelect& s = *m.mutable_select();
    setSentView(s, model, c);
    for (float p : a.pixels()) s.add_lasso(p);
    sendChecked(m, what);
  }

  /// A script's snap: its strokes and this view go to the master, which cuts (SiteSnap).
  void snap(const site::SnapAction& a, const config::Camera& c) {
    const std::string what = "snap " + std::to_string(++snaps_sent);
    const uint32_t model = modelFor(a.model(), what);
    if (!model) return;
    site::ToMaster m;
    site::SiteSnap& s = *m.mutable_snap();
    setSentView(s, model, c);
    for (float p : a.foreground()) s.add_foreground(p);
    for (float p : a.background()) s.add_background(p);
    s.set_heavy_width(a.heavy_width());
    sendChecked(m, what);
  }

  void stroke(const site::StrokeAction& a, const config::Camera& c) {
    site::ToMaster m;
    site::SiteStroke& s = *m.mutable_stroke();
    *s.mutable_color() = a.color();
    s.set_width(a.width() > 0 ? a.width() : 4.0f);
    const uint64_t index = ++strokes;
    if (a.world_size() > 0) {
      for (double v : a.world()) s.add_points(v);
    } else {
      if (!renderer) {
        say("stroke " + std::to_string(index) + " skipped: pixels need rendering (--no-render)");
        return;
      }
      (void)settled(c);
      const render::ViewSetup v = view(c);
      const std::vector<uint32_t> depth = renderer->target().readDepth();
      const glm::dmat4 unproject = glm::inverse(v.projection * v.view);
      // The pixels the stroke passes, at most 2 px apart (as a mouse drag gives them), so the
      // polyline follows the surface between the samples given instead of cutting chords under
      // it.
      std::vector<glm::dvec2> path;
      for (int i = 0; i + 1 < a.pixels_size(); i += 2) {
        const glm::dvec2 p(a.pixels(i), a.pixels(i + 1));
        if (!path.empty()) {
          const int steps = int(std::min(4096.0, std::ceil(glm::length(p - path.back()) / 2.0)));
          const glm::dvec2 from = path.back();
          for (int k = 1; k < steps; ++k) path.push_back(glm::mix(from, p, double(k) / steps));
        }
        path.push_back(p);
      }
      if (path.size() > size_t(kMaxStrokePoints)) path.resize(size_t(kMaxStrokePoints));
      for (const glm::dvec2& pixel : path) {
        const std::optional<Surface> at = surfaceAt(depth, v, unproject, pixel);
        if (!at) continue;  // no surface under it: skipped
        const glm::dvec3 p = at->world;
        s.add_points(p.x);
        s.add_points(p.y);
        s.add_points(p.z);
        if (strokes_csv) {
          char line[256];
          std::snprintf(line, sizeof line, "%llu,%u,%u,%.17g,%.17g,%.17g,%.9g\n",
                        (unsigned long long)index, at->x, at->y, p.x, p.y, p.z, double(at->z));
          strokes_csv << line;
        }
      }
      strokes_csv.flush();
    }
    if (s.points_size() < 6) {
      say("stroke " + std::to_string(index) +
          " skipped: fewer than 2 of its pixels are on the model");
      return;
    }
    say("stroke " + std::to_string(index) + ": " + std::to_string(s.points_size() / 3) +
        " points placed on the model");
    client->send(m);
  }

  void simple(site::ToMaster m) { client->send(m); }

  /// One script action at this frame. False: the site leaves.
  bool act(const site::SiteAction& a, double now) {
    site::ToMaster m;
    switch (a.action_case()) {
      case site::SiteAction::kCamera:
        own = asSent(a.camera());
        following = false;
        break;
      case site::SiteAction::kStroke:
        stroke(a.stroke(), asSent(camera(now)));
        break;
      case site::SiteAction::kNote:
        note(a.note(), asSent(camera(now)));
        break;
      case site::SiteAction::kMeasure:
        measure(a.measure(), asSent(camera(now)));
        break;
      case site::SiteAction::kLasso:
        lasso(a.lasso(), asSent(camera(now)));
        break;
      case site::SiteAction::kSnap:
        snap(a.snap(), asSent(camera(now)));
        break;
      case site::SiteAction::kUndo:
        m.mutable_undo();
        simple(m);
        break;
      case site::SiteAction::kClear:
        m.mutable_clear();
        simple(m);
        break;
      case site::SiteAction::kLead:
        m.mutable_lead();
        simple(m);
        following = false;
        say("leads the view");
        break;
      case site::SiteAction::kRelease:
        m.mutable_release();
        simple(m);
        break;
      case site::SiteAction::kFollow:
        following = true;
        follow_from = own;
        follow_start = now;
        say("follows the view");
        break;
      case site::SiteAction::kScreenshot: {
        if (!renderer) break;
        const std::string path = (fs::path(opt.out_dir) / a.screenshot()).string();
        const config::Camera c = asSent(camera(now));
        render::writePng(path, settled(c));
        char cam[320];
        std::snprintf(cam, sizeof cam, "eye=%.9g,%.9g,%.9g;target=%.9g,%.9g,%.9g;up=%.9g,%.9g,%.9g",
                      c.eye().x(), c.eye().y(), c.eye().z(), c.target().x(), c.target().y(),
                      c.target().z(), c.up().x(), c.up().y(), c.up().z());
        say("wrote " + path + " (scene version " + std::to_string(graph.version()) + "); camera " +
            cam);
        break;
      }
      case site::SiteAction::kBye:
        return false;
      default:
        break;
    }
    return true;
  }

  /// The --window tools' input (tools.tool() != kNone): clicks and drags become pixels of the
  /// measurement, lasso or snap, sent as their script actions when complete.
  void toolInput(render::WindowInput& in, const glm::dvec2& scale, const glm::dvec2& cursor,
                 double now) {
    auto record = [&](std::vector<float>& px, glm::dvec2 q) {
      const size_t n = px.size();
      if (n >= 2 && glm::length(q - glm::dvec2(px[n - 2], px[n - 1])) < 2.0) return;
      if (n >= 2 * 2048) return;  // the most a selection request takes
      px.push_back(float(q.x));
      px.push_back(float(q.y));
    };
    if (tools.tool() == Tool::kNote) {  // a click places the note: the form opens
      if (in.left_pressed) press_at = cursor;
      if (in.left_released && glm::length(cursor - press_at) <= 4.0) {
        note_pixel = cursor;
        note_focus = true;
        tools.choose(Tool::kNone);
        say("note at pixel " + std::to_string(int(cursor.x)) + "," + std::to_string(int(cursor.y)) +
            ": its title and text?");
      }
    } else if (tools.tool() == Tool::kMeasure) {
      if (in.left_pressed) press_at = cursor;
      if (in.left_released && glm::length(cursor - press_at) <= 4.0) {
        record(tool_px, cursor);
        const size_t n = tool_px.size() / 2;
        if ((tools.measureMode() == interact::MeasureTool::Mode::kDistance && n == 2) ||
            (tools.measureMode() == interact::MeasureTool::Mode::kAngle && n == 3))
          sendTool(now);
      }
    } else {
      std::vector<float>& fg = tool_px;
      if (in.left_pressed) fg.clear();
      for (const glm::dvec2& q : in.dragOf(render::WindowInput::kLeftHeld)) record(fg, q * scale);
      if (in.left) record(fg, cursor);
      if (tools.tool() == Tool::kLasso && in.left_released) sendTool(now);
      if (tools.tool() == Tool::kSnap) {  // the right button strokes what not to select
        if (in.right_pressed) snap_bg.clear();
        for (const glm::dvec2& q : in.dragOf(render::WindowInput::kRightHeld))
          record(snap_bg, q * scale);
        if (in.right) record(snap_bg, cursor);
        in.right = false;
      }
    }
    in.left = in.left_pressed = in.left_released = false;  // no navigation meanwhile
  }

  /// The MODEL node under pixel `px` of the last frame (its pick ids), else the first one.
  std::string modelNameAt(float x, float y) {
    if (renderer && x >= 0 && y >= 0 && x < float(script.width()) && y < float(script.height()))
      if (const auto hit = renderer->pick(uint32_t(x), uint32_t(y))) {
        const std::vector<uint32_t>& nodes = models.instanceNodes();
        if (hit->model < nodes.size() && graph.contains(nodes[hit->model]))
          return graph.node(nodes[hit->model]).name();
      }
    return {};
  }

  /// Sends what the current tool has (Enter, or a measurement's last click, or the lasso's
  /// release) as its script action, then starts over.
  void sendTool(double now) {
    site::SiteAction a;
    if (tools.tool() == Tool::kMeasure) {
      a.mutable_measure()->set_type(interact::MeasureTool::typeOf(tools.measureMode()));
      for (float v : tool_px) a.mutable_measure()->add_pixels(v);
    } else if (tools.tool() == Tool::kLasso) {
      if (tool_px.size() < 6) return tool_px.clear();
      a.mutable_lasso()->set_model(modelNameAt(tool_px[0], tool_px[1]));
      for (float v : tool_px) a.mutable_lasso()->add_pixels(v);
    } else if (tools.tool() == Tool::kSnap) {
      if (tool_px.empty()) return say("snap: first stroke what to select (left drag)");
      site::SnapAction& sn = *a.mutable_snap();
      sn.set_model(modelNameAt(tool_px[0], tool_px[1]));
      for (float v : tool_px) sn.add_foreground(v);
      for (float v : snap_bg) sn.add_background(v);
      if (snap_bg.empty()) sn.set_heavy_width(16.0f);  // one stroke around: the robust lasso
    } else {
      return;
    }
    tool_px.clear();
    snap_bg.clear();
    act(a, now);
  }

  /// The new note's form (Dear ImGui, between the window's beginUi() and endUi()), while a
  /// note is being placed.
  void noteForm(double now) {
    if (!note_pixel) return;
    bool open = true;
    ImGui::SetNextWindowPos(ImVec2(8.0f, 8.0f), ImGuiCond_Appearing);
    ImGui::SetNextWindowSizeConstraints(ImVec2(300.0f, 0.0f), ImVec2(300.0f, FLT_MAX));
    if (ImGui::Begin("New note", &open, ImGuiWindowFlags_AlwaysAutoResize)) {
      ImGui::PushItemWidth(-48.0f);
      ImGui::InputText("layer", note_layer, sizeof note_layer);
      if (note_focus) {
        ImGui::SetKeyboardFocusHere();
        note_focus = false;
      }
      const bool enter = ImGui::InputText("title", note_title, sizeof note_title,
                                          ImGuiInputTextFlags_EnterReturnsTrue);
      ImGui::InputTextMultiline("text", note_text, sizeof note_text, ImVec2(-48.0f, 54.0f));
      ImGui::PopItemWidth();
      if (ImGui::Button("Add (Enter)") || enter) {
        if (note_title[0] == '\0') {
          say("a note needs a title");
        } else {
          site::SiteAction a;
          site::NoteAction& na = *a.mutable_note();
          na.add_pixel(float(note_pixel->x));
          na.add_pixel(float(note_pixel->y));
          site::NoteContent& item = *na.mutable_note()->mutable_add()->mutable_item();
          item.set_layer(note_layer);
          item.set_kind("text");
          item.set_title(note_title);
          item.set_text(note_text);
          note_pixel.reset();
          note_title[0] = note_text[0] = '\0';
          act(a, now);
        }
      }
      ImGui::SameLine();
      if (ImGui::Button("Cancel")) open = false;
    }
    ImGui::End();
    if (!open) note_pixel.reset();
  }

  /// What a key asks of this site's window (interact/keys.h: the console's keys).
  void key(interact::KeyPress press, const glm::dvec2& cursor, double now) {
    using interact::Command;
    site::SiteAction a;
    switch (press.command) {
      case Command::kAddNote:
      case Command::kMeasure:
      case Command::kLasso:
      case Command::kSnap:
        say(tools.press(press.command));
        tool_px.clear();
        snap_bg.clear();
        return;
      case Command::kEnd:
        sendTool(now);
        return;
      case Command::kBack:  // the last click, or the strokes
        if (tools.tool() == Tool::kMeasure && tool_px.size() >= 2) {
          tool_px.resize(tool_px.size() - 2);
        } else {
          tool_px.clear();
          snap_bg.clear();
        }
        return;
      case Command::kOpenNote: {  // open or close the note nearest the cursor
        const auto node = interact::noteNear(graph, last_view, cursor, 24.0);
        if (!node) {
          say("no note within 24 px of the cursor");
          return;
        }
        const scene::AnnotationPayload& n = graph.node(*node).annotation();
        if (n.place() == 0) {
          say("that note is not in the database: it cannot be opened");
          return;
        }
        site::PlaceOpen& open = *a.mutable_note()->mutable_note()->mutable_open();
        open.set_place(n.place());
        open.set_open(!n.open());
        break;
      }
      case Command::kLead:
        a.set_lead(true);
        break;
      case Command::kRelease:
        a.set_release(true);
        break;
      case Command::kFollow:
        a.set_follow(true);
        break;
      case Command::kUndoSketch:
        a.set_undo(true);
        break;
      case Command::kClearSketches:
        a.set_clear(true);
        break;
      case Command::kPicture:
        a.set_screenshot("site-" + std::to_string(uint64_t(now * 1000)) + ".png");
        break;
      default:  // the console's own (section clip, models, opacity, lighting)
        return;
    }
    act(a, now);
  }

  /// --window: the user's input since the last frame. False when the window closes.
  bool interact(double now) {
    render::WindowInput in = window->poll();
    if (window->closing()) return false;
    // The note form first: what it takes (the mouse over it, the keyboard in a field) the view
    // does not also get.
    window->beginUi();
    noteForm(now);
    window->endUi();
    if (window->uiWantsMouse()) {
      in.left = in.left_pressed = in.left_released = false;
      in.scroll = 0.0;
      in.path.clear();
      in.path_buttons.clear();
      if (!right_held) in.right = false;
    }
    if (window->uiWantsKeyboard()) in.keys.clear();
    const auto t = Clock::now();
    const double dt = std::chrono::duration<double>(t - last_input).count();
    last_input = t;
    const glm::dvec2 scale(script.width() / std::max(1.0, double(in.size.x)),
                           script.height() / std::max(1.0, double(in.size.y)));
    interact::PointerInput p;
    p.cursor = in.cursor * scale;
    p.down = in.left;
    p.pressed = in.left_pressed;
    p.released = in.left_released;
    p.scroll = in.scroll;
    p.size = glm::dvec2(script.width(), script.height());
    if (tools.tool() != Tool::kNone) {
      toolInput(in, scale, p.cursor, now);
      p.down = p.pressed = p.released = false;
    }
    if (p.pressed || p.down || p.released || p.scroll != 0 || navigation.flying()) {
      if (following && (p.pressed || p.scroll != 0)) {
        following = false;  // taking control back
        say("stops following");
      }
      const glm::dmat4 clip_from_world = last_view.projection * last_view.view;
      const double fovy = glm::radians(double(script.fovy_deg()));
      auto pick = [&](glm::dvec2 px) -> std::optional<glm::dvec3> {
        if (!(px.x >= 0 && px.y >= 0 && px.x < script.width() && px.y < script.height()))
          return std::nullopt;
        if (auto hit = renderer->pick(uint32_t(px.x), uint32_t(px.y))) return hit->world;
        return std::nullopt;
      };
      auto project = [&](const glm::dvec3& w) -> std::optional<glm::dvec2> {
        const glm::dvec4 c = clip_from_world * glm::dvec4(w, 1.0);
        if (c.w <= 0) return std::nullopt;
        return glm::dvec2((c.x / c.w * 0.5 + 0.5) * script.width(),
                          (0.5 - c.y / c.w * 0.5) * script.height());
      };
      if (!following) own = navigation.update(own, p, dt, fovy, pick, project);
    }
    // A right-button drag draws a stroke, placed on the model when the button goes up.
    const glm::vec2 at(p.cursor);
    if (in.right) {
      if (drag.empty() || glm::length(at - glm::vec2(drag[drag.size() - 2], drag.back())) >= 1.0f) {
        drag.push_back(at.x);
        drag.push_back(at.y);
      }
    } else if (right_held) {
      if (drag.size() >= 4) {
        site::StrokeAction a;
        for (float v : drag) a.add_pixels(v);
        *a.mutable_color() = welcome.color();
        a.set_width(4.0f);
        stroke(a, asSent(camera(now)));
      }
      drag.clear();
    }
    right_held = in.right;
    for (int k : in.keys) key(interact::commandOf(k), p.cursor, now);
    const std::string& leader = graph.settings().leader();
    window->setTitle(
        "tessera-site: " + welcome.name() +
        (leader == welcome.name() ? " | leading the view"
         : following ? " | following " + (leader.empty() ? std::string("the wall") : leader)
                     : "") +
        " | left: navigate, right: draw; " + interact::keysHelp(kSiteKeys) + ", Esc quit");
    return true;
  }

  int session() {
    if (!opt.script.empty())
      script = loadSiteScript(opt.script);
    else
      withDefaults(script);
    if (opt.window) {
      script.set_width(opt.window_width);
      script.set_height(opt.window_height);
    }
    if (opt.render) {
      if (opt.window) {
        window = render::Window::open(script.width(), script.height(),
                                      "tessera-site: " + opt.client.name);
        window->enableUi();  // the note form (A)
      } else {
        context = render::GlContext::createHeadless();
      }
      render::StreamerOptions stream;
      stream.density_ratios = true;
      // Loaders reading over the link mostly wait: more of them keep more requests in flight
      // (Bettio et al. 4: pipelined requests), as many as fill the link.
      if (opt.remote_stores || !opt.cache_dir.empty()) stream.loader_threads = 8;
      stream.cancel_after_frames = opt.withdraw_after_frames;
      renderer =
          std::make_unique<render::ViewRenderer>(script.width(), script.height(), nullptr, stream);
      std::error_code ec;
      fs::create_directories(opt.out_dir, ec);
      strokes_csv.open(fs::path(opt.out_dir) / "strokes.csv");
      if (!strokes_csv)
        throw std::runtime_error(
            "-o " + opt.out_dir + ": cannot write strokes.csv: " +
            whyNotWritable((fs::path(opt.out_dir) / "strokes.csv").string(), errno));
      strokes_csv << "stroke,px,py,x,y,z,depth\n";
    }
    if (!opt.audio_in.empty() || !opt.audio_out.empty()) {
      const media::VoiceSettings voice;
      const auto say_device = [this](const std::string& line) { say(line); };
      const std::optional<std::string> in_device = media::alsaDeviceOf(opt.audio_in);
      const std::optional<std::string> out_device = media::alsaDeviceOf(opt.audio_out);
      if (in_device) {
        microphone = std::make_unique<media::AlsaMicrophone>(*in_device, voice.frameSamples(), say_device);
        say("voice: microphone " + microphone->pcm().describe());
      }
      if (out_device) {
        speaker =
            std::make_unique<media::AlsaSpeaker>(*out_device, voice.frameSamples(), 0.08, say_device);
        say("voice: speaker " + speaker->pcm().describe());
      }
      station = std::make_unique<media::VoiceStation>(voice, opt.audio_in.empty() || in_device
                                                          ? std::vector<float>{}
                                                          : media::readVoiceWav(opt.audio_in));
      station->setLive(microphone != nullptr, speaker != nullptr);
      opt.client.voice = [this](std::string_view bytes) {
        station->receive({reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()},
                         voiceNow());
      };
    }
    if (renderer) {
      videos = std::make_unique<render::VideoTextures>();
      opt.client.video = [this](std::string_view bytes) {
        videos->receive({reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()});
      };
    }
    if (!opt.video.empty()) {
      video_source = media::openVideoSource(opt.video, opt.video_settings.width, opt.video_settings.height,
                                     opt.video_settings.fps);
    }
    opt.client.note = [this](const site::SiteNoteAnswer& a) {
      if (a.ok())
        say("note " + std::to_string(a.request()) + " committed" +
            (a.item() ? ": item " + std::to_string(a.item()) + " revision " +
                            std::to_string(a.revision())
                      : std::string()) +
            (a.place() ? " at place " + std::to_string(a.place()) : std::string()));
      else
        say("note " + std::to_string(a.request()) + (a.conflict() ? " conflict: " : " refused: ") +
            a.error());
    };
    client = std::make_unique<SiteClient>(opt.client);
    welcome = client->join(
        graph, Clock::now() + std::chrono::milliseconds(int64_t(opt.join_timeout_s * 1000)));
    voice_start = Clock::now();
    if (video_source) {
      video_sender =
          std::make_unique<media::VideoSender>(opt.video_settings, uint16_t(welcome.participant()));
      video_next = Clock::now();
      say("sends video: " + video_source->describe() + ", H.264 " +
          std::to_string(opt.video_settings.kbps) + " kbit/s");
    }
    {
      char line[200];
      std::snprintf(line, sizeof line,
                    "joined as participant %u at scene version %llu (snapshot %zu bytes, %.3f s)",
                    welcome.participant(), (unsigned long long)graph.version(),
                    welcome.snapshot().size(), elapsed());
      say(line);
    }
    if (!welcome.chunks().empty() && opt.render) {
      ChunkClientOptions co;
      co.endpoint = chunkEndpointFor(welcome.chunks(), opt.client.master);
      co.master_key = opt.client.master_key;
      co.keys = opt.client.keys;
      co.cache_dir = opt.cache_dir;
      co.cache_limit_bytes = uint64_t(opt.cache_mb * 1e6);
      co.timeout_s = opt.chunk_timeout_s;
      chunks = std::make_unique<ChunkClient>(co);
      say("chunks from " + co.endpoint +
          (co.cache_dir.empty() ? std::string(" (no disk cache)") : ", cached in " + co.cache_dir));
    } else if (opt.remote_stores && opt.render) {
      throw lod::StoreError(
          "--remote-stores: the master serves no chunks (start it with --chunks)");
    }
    models.setStoreOpener([this](const std::string& path) {
      return openStore<lod::PointStore>(path, "lod::PointStore");
    });
    models.setMeshStoreOpener([this](const std::string& path) {
      return openStore<lod::MeshStore>(path, "lod::MeshStore");
    });
    update(sync::SceneChanges::all());
    own = graph.camera();
    const auto period = std::chrono::duration<double>(1.0 / script.fps());
    const auto start = Clock::now();
    int next_action = 0;
    for (uint64_t frame = 0;; ++frame) {
      const auto tick = start + std::chrono::duration_cast<Clock::duration>(period * double(frame));
      sleepSendingVideo(tick);
      const double now = std::chrono::duration<double>(Clock::now() - start).count();
      update(client->receive(graph, Clock::now()));
      while (next_action < script.actions_size() && script.actions(next_action).frame() <= frame) {
        if (!act(script.actions(next_action++), now)) {
          site::ToMaster bye;
          bye.mutable_bye();
          client->send(bye);
          say("left");
          return kSiteOk;
        }
      }
      if (window && !interact(now)) {
        site::ToMaster bye;
        bye.mutable_bye();
        client->send(bye);
        say("left (its window closed)");
        return kSiteOk;
      }
      const config::Camera c = asSent(camera(now));
      sendPose(c);
      if (renderer) {
        last_view = view(c);
        if (videos) {  // other sites' insets: decode those in view, upload what is new
          render::SceneOverlayOptions so;
          so.screen_wall = so.screen_view = glm::dvec4(0.0, 0.0, script.width(), script.height());
          so.view_px = glm::dvec2(script.width(), script.height());
          so.video_texture = [this](uint32_t source) { return videos->texture(source); };
          videos->setShown(render::shownVideoSources(graph, last_view, so));
          videos->upload();
        }
        const render::Overlay o = overlay(c);
        render::RenderStats st;
        renderer->draw(instances, last_view, options(), &st, o.empty() ? nullptr : &o);
        noteProgress(st);
        if (window) window->present(renderer->imageBuffer(), script.width(), script.height());
      }
      if (script.frames() > 0 && frame + 1 >= script.frames()) {
        site::ToMaster bye;
        bye.mutable_bye();
        client->send(bye);
        say("left after " + std::to_string(script.frames()) + " frames");
        return kSiteOk;
      }
    }
  }
};

SiteSession::SiteSession(SiteSessionOptions options) : m(std::make_unique<Impl>()) {
  m->opt = std::move(options);
}

SiteSession::~SiteSession() = default;

int SiteSession::run() {
  const int code = runSession();
  m->writeSpeaker();
  m->sayVideo();
  return code;
}

int SiteSession::runSession() {
  try {
    return m->session();
  } catch (const media::WavError& e) {
    std::fprintf(stderr, "tessera-site: --audio-in: %s\n", e.what());
    return kSiteFailed;
  } catch (const media::AlsaError& e) {
    std::fprintf(stderr, "tessera-site: --audio-in/--audio-out: %s\n", e.what());
    return kSiteFailed;
  } catch (const media::VideoError& e) {
    std::fprintf(stderr, "tessera-site: --video: %s\n", e.what());
    return kSiteFailed;
  } catch (const SiteSessionEnded& e) {
    switch (e.why) {
      case Why::kQuit:
        m->say(e.what());
        return kSiteOk;
      case Why::kRefused:
      case Why::kDropped:
        std::fprintf(stderr, "tessera-site: %s\n", e.what());
        return kSiteRefused;
      case Why::kMasterLost:
        std::fprintf(stderr, "tessera-site: %s\n", e.what());
        return kSiteMasterLost;
      default:
        std::fprintf(stderr, "tessera-site: %s\n", e.what());
        return kSiteFailed;
    }
  } catch (const sync::ConfigError& e) {
    std::fprintf(stderr, "tessera-site: %s\n", e.what());
    return kSiteFailed;
  } catch (const render::RenderError& e) {
    std::fprintf(stderr, "tessera-site: no usable GL: %s\n", e.what());
    return kSiteFailed;
  } catch (const lod::StoreError& e) {
    std::fprintf(stderr, "tessera-site: %s\n", e.what());
    return kSiteFailed;
  }
}

}  // namespace tessera::collab
