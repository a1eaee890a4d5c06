// SiteSession's parts (collab/site_session.h), for the files that make it up; not installed.
//   site_session.cpp          the session: joining, the frame loop, the view, stores, pictures
//   site_session_actions.cpp  what the site asks of the master: notes, measurements, selections,
//                             strokes, and the script's actions
//   site_session_window.cpp   --window: the keyboard (interact/keys.h), the tools' clicks and
//                             drags, the note form
//   site_session_media.cpp    --audio-in/--audio-out and --video: voice and video, paced by the loop
//   site_script.cpp           the site script file: loading, checking, defaults
#pragma once

#include <tessera/collab/site_session.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <tuple>
#include <type_traits>

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

namespace fs = std::filesystem;
using sync::vec;
using Clock = std::chrono::steady_clock;
using Why = SiteSessionEnded::Why;

/// The camera every process of the session would decode from it (the wire's rounding), so a
/// leader and its followers render the very same view.
config::Camera asSent(const config::Camera& c);

/// The script's defaults where it is silent: 30 frames a second, 640x480, 45 degrees.
void withDefaults(site::SiteScript& s);

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
  // O opens a note: its panel lists its items, and each text, number or link item can be
  // edited (the form takes the keyboard; Enter or save sends SiteNote update, based on the
  // revision the scene showed) or deleted (SiteNote remove).
  uint32_t note_shown = 0;  // the ANNOTATION node whose panel is up (0: none)
  struct NoteEdit {
    uint64_t item = 0, base_revision = 0;
    std::string kind, unit, uri;
    uint64_t link_item = 0;
    char title[1025] = "", text[2048] = "";
    double number = 0.0;
    bool focus = true;
  };
  std::optional<NoteEdit> note_edit;
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
  void pumpVideo();

  /// Sleeps until `until`, sending the pictures that fall due meanwhile: video keeps its own
  /// rate whatever the loop's.
  void sleepSendingVideo(Clock::time_point until);

  void sayVideo();

  double voiceNow() const;

  /// Sends the microphone's frames that are due and plays the speaker's blocks (every frame).
  void tickVoice();

  /// --audio-out: what it heard, written when the session ends however it ends.
  void writeSpeaker();

  ~Impl();

  void say(const std::string& text);

  void update(const sync::SceneChanges& changes);

  /// A perspective view of `camera` whose depth range holds every model.
  render::ViewSetup view(const config::Camera& camera) const;

  /// Every sketch and avatar but its own and any at its eye (its leader's, when it follows).
  render::Overlay overlay(const config::Camera& c) const;

  /// The camera this site shows now.
  config::Camera camera(double now);

  void sendPose(const config::Camera& c);

  render::RenderOptions options() const;

  double elapsed() const { return std::chrono::duration<double>(Clock::now() - started).count(); }

  /// Frames until the whole cut is resident (render::ViewRenderer::renderSettled(), but the
  /// link goes on meanwhile: frames are applied and poses sent while chunks arrive, which over
  /// a slow link may take many seconds).
  render::Image settled(const config::Camera& c);

  /// Opens a store the scene names (a lod::PointStore or lod::MeshStore): from this host, or
  /// from the master's chunk server.
  /// A see-through mesh's points (MESH#points) are on this host when the mesh is: sampled here,
  /// as the master and its nodes do.
  template <class Store>
  std::unique_ptr<Store> openStore(const std::string& path, const char* kind);

  /// After a frame: when this site first showed data, and when its view first settled (join
  /// time, bench/sites).
  void noteProgress(const render::RenderStats& st);

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
                                          glm::dvec2 pixel);

  /// A script's note: a new place under a pixel is placed on the surface there (its model
  /// named by the pick ids), a hot spot without a view gets this camera; then it is checked as
  /// the master will check it, and sent.
  void note(const site::NoteAction& a, const config::Camera& c);

  /// A script's measurement: each pixel picked on the full-resolution surface under it (the
  /// stores, or the chunks the master serves), measured here, checked as the master will
  /// check it, and sent.
  void measure(const site::MeasureAction& a, const config::Camera& c);

  /// The MODEL node named `name` (the first MODEL node when empty), or 0 (said, as `what`).
  uint32_t modelFor(const std::string& name, const std::string& what);

  /// Fills a SiteSelect's or SiteSnap's model and view from this site's view `c`.
  template <class M>
  void setSentView(M& s, uint32_t model, const config::Camera& c);

  /// Checks and sends a selection request.
  void sendChecked(const site::ToMaster& m, const std::string& what);

  /// A script's lasso: its pixels and this view go to the master, which selects (SiteSelect).
  void lasso(const site::LassoAction& a, const config::Camera& c);

  /// A script's snap: its strokes and this view go to the master, which cuts (SiteSnap).
  void snap(const site::SnapAction& a, const config::Camera& c);

  void stroke(const site::StrokeAction& a, const config::Camera& c);

  void simple(site::ToMaster m) { client->send(m); }

  /// One script action at this frame. False: the site leaves.
  bool act(const site::SiteAction& a, double now);

  /// The --window tools' input (tools.tool() != kNone): clicks and drags become pixels of the
  /// measurement, lasso or snap, sent as their script actions when complete.
  void toolInput(render::WindowInput& in, const glm::dvec2& scale, const glm::dvec2& cursor,
                 double now);

  /// The MODEL node under pixel `px` of the last frame (its pick ids), else the first one.
  std::string modelNameAt(float x, float y);

  /// Sends what the current tool has (Enter, or a measurement's last click, or the lasso's
  /// release) as its script action, then starts over.
  void sendTool(double now);

  /// The new note's form (Dear ImGui, between the window's beginUi() and endUi()), while a
  /// note is being placed.
  void noteForm(double now);

  /// The opened note's panel (Dear ImGui, as noteForm): its items, and their edit and delete.
  void notePanel(double now);

  /// What a key asks of this site's window (interact/keys.h: the console's keys).
  void key(interact::KeyPress press, const glm::dvec2& cursor, double now);

  /// --window: the user's input since the last frame. False when the window closes.
  bool interact(double now);

  int session();
};

}  // namespace tessera::collab
