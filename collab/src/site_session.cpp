// A site session: joins the master, mirrors its scene, renders its own view from the stores (or
// their chunks from the master), sends its pose, and runs the frame loop; what it asks of the
// master, its window and its media are in the files beside this one (site_session_impl.h).
#include "site_session_impl.h"

#include <csignal>

#include <tessera/core/cli.h>

namespace tessera::collab {

SiteSession::Impl::~Impl() {
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

void SiteSession::Impl::say(const std::string& text) {
  std::printf("tessera-site %s: %s\n",
              welcome.name().empty() ? opt.client.name.c_str() : welcome.name().c_str(),
              text.c_str());
  std::fflush(stdout);
}

void SiteSession::Impl::update(const sync::SceneChanges& changes) {
  if (!renderer || changes.empty()) return;
  render::ChunkStreamer* s[] = {&renderer->streamer()};
  instances = models.update(graph, changes, s);
}

render::ViewSetup SiteSession::Impl::view(const config::Camera& camera) const {
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

render::Overlay SiteSession::Impl::overlay(const config::Camera& c) const {
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

config::Camera SiteSession::Impl::camera(double now) {
  if (!following) return own;
  const config::Camera target = graph.camera();
  const double s = std::clamp((now - follow_start) / 0.5, 0.0, 1.0);
  own = s >= 1.0 ? target : blendCameras(follow_from, target, s * s * (3.0 - 2.0 * s));
  return own;
}

void SiteSession::Impl::sendPose(const config::Camera& c) {
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

render::RenderOptions SiteSession::Impl::options() const {
  render::RenderOptions o = render::SceneDrawList::options(graph, 2.0f);
  o.pick_ids = want_pick;                         // a note placed under a pixel names its model
  o.highlights = render::sceneHighlights(graph);  // selections, as the wall tints them
  return o;
}

render::Image SiteSession::Impl::settled(const config::Camera& c) {
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
    update(
        client->receive(graph, Clock::now() + std::chrono::duration_cast<Clock::duration>(period)));
    sendPose(c);
  }
  return img;
}

template <class Store>
std::unique_ptr<Store> SiteSession::Impl::openStore(const std::string& path, const char* kind) {
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
    throw lod::StoreError(std::string(kind) + ": " + path + ": from the chunk server: " + e.what());
  }
}

void SiteSession::Impl::noteProgress(const render::RenderStats& st) {
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
  if (first_image && !view_settled && st.stream.requested == 0 && st.stream.pages_requested == 0 &&
      st.stream.queued == 0) {
    view_settled = true;
    note("view settled");
  }
}

int SiteSession::Impl::session() {
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
      window =
          render::Window::open(script.width(), script.height(), "tessera-site: " + opt.client.name);
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
      microphone =
          std::make_unique<media::AlsaMicrophone>(*in_device, voice.frameSamples(), say_device);
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
      station->receive({reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()}, voiceNow());
    };
  }
  if (renderer) {
    videos = std::make_unique<render::VideoTextures>();
    opt.client.video = [this](std::string_view bytes) {
      videos->receive({reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()});
    };
  }
  if (!opt.video.empty()) {
    video_source = media::openVideoSource(opt.video, opt.video_settings.width,
                                          opt.video_settings.height, opt.video_settings.fps);
  }
  opt.client.note = [this](const site::SiteNoteAnswer& a) {
    if (a.ok())
      say("note " + std::to_string(a.request()) + " committed" +
          (!a.item()         ? std::string()
           : a.revision() == 0 ? ": item " + std::to_string(a.item()) + " removed"
                               : ": item " + std::to_string(a.item()) + " revision " +
                                     std::to_string(a.revision())) +
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
    throw lod::StoreError("--remote-stores: the master serves no chunks (start it with --chunks)");
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
    if (const int sig = cli::stopSignal()) {
      site::ToMaster bye;
      bye.mutable_bye();
      client->send(bye);
      say(std::string("left (") + (sig == SIGINT ? "SIGINT" : "SIGTERM") + ")");
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
