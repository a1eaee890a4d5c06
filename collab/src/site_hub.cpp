#include <tessera/collab/site_hub.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <span>

#include <glm/glm.hpp>
#include <zmq.hpp>

#include <tessera/collab/chunk_server.h>
#include <tessera/collab/curve.h>
#include <tessera/collab/site_messages.h>
#include <tessera/collab/site_notes.h>
#include <tessera/collab/site_selections.h>
#include <tessera/media/video_packet.h>
#include <tessera/media/voice_alsa.h>
#include <tessera/media/voice_bridge.h>
#include <tessera/media/voice_wav.h>
#include <tessera/render/scene_draw_list.h>
#include <tessera/sync/cluster_link.h>
#include <tessera/sync/wire.h>

#include "server_socket.h"
#include "token_bucket.h"

namespace tessera::collab {

namespace {

using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point t) {
  return std::chrono::duration<double>(t.time_since_epoch()).count();
}

/// A connection on the site socket (one routing id).
struct Peer {
  std::string id, key;       // routing id; the Z85 key CURVE authenticated
  uint32_t participant = 0;  // 0 until welcomed
  double last_seen = 0;
  TokenBucket messages, bytes, video;
  double video_warned = -1e9;  // when the master last said this site's video is over its cap
  uint64_t video_dropped = 0;
  bool behind = false, gone = false;
  std::string gone_reason;
};

std::string shortKey(const std::string& key) {
  return key.substr(0, 8);
}

}  // namespace

struct SiteHub::Impl {
  SiteHubOptions opt;
  KeyPair keys;
  std::shared_ptr<AllowList> allow;
  zmq::context_t context{1};
  std::unique_ptr<ZapHandler> zap;
  zmq::socket_t socket;
  std::unique_ptr<ChunkServer> chunks;  // in `context`: the same ZAP handler admits its sites
  SiteRoster roster;
  std::map<std::string, Peer> peers;        // by routing id
  std::map<std::string, double> discarded;  // routing ids of dropped sites -> since
  uint64_t allow_generation = 0;
  double last_reload = 0;
  SiteHubCounters counters;
  annotate::AnnotationScene* notes = nullptr;
  std::unique_ptr<SiteSelections> selections;       // made with the first lasso
  std::unique_ptr<media::VoiceBridge> voice;               // with opt.voice
  std::unique_ptr<media::AlsaMicrophone> wall_microphone;  // --audio-in alsa:DEVICE
  std::unique_ptr<media::AlsaSpeaker> wall_speaker;        // --audio-out alsa:DEVICE
  std::deque<float> room_queue;                     // the room's mix not yet on wall_speaker
  double voice_start = 0;
  /// A site's video inset: its VIDEO_INSET node and when its last chunk came.
  struct Inset {
    sync::SceneGraph::NodeId node = 0;
    double last = 0;
    bool owned = true;  // made by the hub (false: the scene's own, pinned by its file)
  };
  std::map<uint32_t, Inset> insets;  // by participant
  std::vector<std::string> media;    // video chunks for the nodes with the next frame
  size_t media_bytes = 0;
  /// Media held for one frame at most: a frame that is slow to come does not pile up chunks.
  static constexpr size_t kMaxMediaBytes = 8u << 20;

  /// The participant's VIDEO_INSET node, made at its first chunk: a child of its avatar, beside
  /// the head, a quarter of the avatar's reach (its distance to what it looks at) wide and
  /// resized when the reach changes by a quarter (so it keeps its size among what the site looks
  /// at), or pinned to the screen. Beside an avatar that has no pose yet: made at a later chunk.
  void showInset(sync::SceneGraph& graph, const Peer& p, const media::VideoPacket& packet, double now) {
    Inset& in = insets[p.participant];
    in.last = now;
    const bool exists = in.node && graph.contains(in.node);
    if (exists && (!in.owned || opt.video_screen)) return;
    if (!exists) {
      // A VIDEO_INSET the scene already has for this participant (a scene file pinned it in
      // the world): that one shows the stream, and stays when the video stops.
      for (const sync::SceneGraph::NodeId id : graph.ids()) {
        const scene::SceneNode& n = graph.node(id);
        if (n.kind() == scene::SceneNode::VIDEO_INSET &&
            n.video_inset().source() == p.participant) {
          in.node = id;
          in.owned = false;
          return;
        }
      }
    }
    const SiteInfo& info = roster.info(p.participant);
    scene::VideoInsetPayload v;
    v.set_stream(info.name);
    v.set_source(p.participant);
    const double aspect = double(packet.height) / double(packet.width);
    if (opt.video_screen) {
      // The k-th inset to the right of the one before while there is room, then to the left
      // of the first (beyond both edges they pile up at the edge).
      const size_t k = insets.size() - 1;
      const float w = std::clamp(opt.screen_width, 0.01f, 1.0f), step = w * 1.05f;
      float x = opt.screen_x + float(k) * step;
      if (x + w > 1.0f) {
        const float right = std::floor((1.0f - w - opt.screen_x) / step) + 1.0f;
        x = opt.screen_x - (float(k) - right + 1.0f) * step;
      }
      v.set_screen(true);
      v.set_screen_x(std::clamp(x, 0.0f, 1.0f - w));
      v.set_screen_y(std::clamp(opt.screen_y, 0.0f, 1.0f));
      v.set_screen_width(w);
      v.set_screen_height(0.0f);  // the renderer keeps the picture's aspect
      if (!exists) {
        in.node = graph.add(scene::SceneNode::VIDEO_INSET, sync::SceneGraph::kRoot,
                            "video: " + info.name, v, info.name);
      }
    } else {
      if (!info.avatar || !graph.contains(info.avatar)) return;
      const float reach = graph.node(info.avatar).avatar().reach();
      if (!(reach > 0.0f)) return;  // no pose yet: its size would be a guess
      const double width = 0.25 * double(reach);
      if (exists) {
        const double shown = graph.node(in.node).video_inset().width();
        if (std::abs(width - shown) <= 0.25 * shown) return;
      }
      v.set_width(float(width));
      v.set_height(float(width * aspect));
      // Right of the head, its top edge level with the eye (the avatar frame: x right, y up).
      glm::dmat4 m(1.0);
      m[3] = glm::dvec4(0.6 * width, -0.5 * width * aspect, 0.0, 1.0);
      const std::span<const double> beside(&m[0][0], 16);
      if (exists)
        graph.setTransform(in.node, beside);
      else
        in.node = graph.add(scene::SceneNode::VIDEO_INSET, info.avatar, "video: " + info.name, v,
                            info.name, beside);
    }
    if (exists) {
      graph.setPayload(in.node, v);
      graph.setAuthor(in.node, info.name);
      return;
    }
    say(who(p) + " sends video (" + std::to_string(packet.width) + "x" +
        std::to_string(packet.height) + "): inset " + std::to_string(in.node) +
        (opt.video_screen ? " pinned to the screen" : " beside its avatar"));
  }

  void removeInset(sync::SceneGraph& graph, uint32_t participant) {
    auto it = insets.find(participant);
    if (it == insets.end()) return;
    if (it->second.owned && it->second.node && graph.contains(it->second.node))
      graph.remove(it->second.node);
    insets.erase(it);
  }

  /// A checked video chunk from a welcomed site.
  void video(sync::SceneGraph& graph, Peer& p, const std::string& bytes, double now) {
    counters.video_in++;
    if (!p.video.take(double(bytes.size()), now)) {
      counters.video_dropped++;
      p.video_dropped++;
      if (now - p.video_warned >= 1.0) {
        p.video_warned = now;
        say(who(p) + ": video over its cap of " + std::to_string(int(opt.video_cap_kbps)) +
            " kbit/s: chunks dropped (" + std::to_string(p.video_dropped) + " so far)");
      }
      return;
    }
    std::vector<uint8_t> chunk(bytes.begin(), bytes.end());
    media::VideoPacket packet;
    if (media::decodeVideoPacket(chunk, packet)) return;  // cannot happen: checked by parseToMaster
    showInset(graph, p, packet, now);
    // Its site field says who sent it, as the link authenticated, whatever the site wrote.
    media::setVideoPacketSite(chunk, uint16_t(p.participant));
    std::string forwarded(chunk.begin(), chunk.end());
    if (media_bytes + forwarded.size() <= kMaxMediaBytes) {
      media_bytes += forwarded.size();
      media.push_back(forwarded);
      counters.video_to_nodes++;
    }
    site::ToSite out;
    out.set_video(std::move(forwarded));
    const std::string out_bytes = out.SerializeAsString();
    for (auto& [rid, other] : peers)
      if (other.participant && other.participant != p.participant && !other.gone &&
          send(other, out_bytes))
        counters.video_to_sites++;
  }

  void say(const std::string& text) {
    std::printf("tessera-master: sites: %s\n", text.c_str());
    std::fflush(stdout);
  }

  std::string who(const Peer& p) const {
    return p.participant ? roster.info(p.participant).name + " (key " + shortKey(p.key) + ")"
                         : "a site (key " + shortKey(p.key) + ")";
  }

  /// Sends one message; false when the site is gone (EHOSTUNREACH) or its queue is full.
  bool send(Peer& p, const std::string& bytes) {
    try {
      if (!socket.send(zmq::buffer(p.id), zmq::send_flags::sndmore | zmq::send_flags::dontwait))
        return false;
      socket.send(zmq::buffer(bytes), zmq::send_flags::dontwait);
      counters.messages_out++;
      counters.bytes_out += bytes.size();
      return true;
    } catch (const zmq::error_t& e) {
      if (e.num() == EHOSTUNREACH) {
        p.gone = true;
        p.gone_reason = "its connection closed";
      }
      return false;
    }
  }

  /// Removes a peer: its avatar goes, its lead ends; its sketches stay in the scene. A dropped
  /// peer is told why and its later messages are discarded unread.
  void remove(sync::SceneGraph& graph, const std::string& id, const std::string& why,
              bool dropped) {
    auto it = peers.find(id);
    if (it == peers.end()) return;
    Peer& p = it->second;
    say(who(p) + (dropped ? " dropped: " : " left: ") + why);
    if (p.participant) removeInset(graph, p.participant);
    if (p.participant) roster.leave(graph, p.participant);
    if (p.participant && voice) voice->leave(p.participant);
    if (dropped) {
      site::ToSite m;
      m.mutable_dropped()->set_reason(why);
      send(p, m.SerializeAsString());
      discarded[id] = seconds(Clock::now());
      counters.dropped++;
    } else {
      counters.left++;
    }
    peers.erase(it);
  }

  void welcome(sync::SceneGraph& graph, Peer& p, const site::SiteHello& hello) {
    if (hello.protocol() != sync::kProtocolVersion) {
      site::ToSite m;
      m.mutable_refused()->set_reason("protocol " + std::to_string(hello.protocol()) +
                                      ", this master speaks " +
                                      std::to_string(sync::kProtocolVersion));
      send(p, m.SerializeAsString());
      counters.refused++;
      say("refused " + who(p) + ": " + m.refused().reason());
      p.gone = true;
      p.gone_reason = "refused";
      return;
    }
    // The snapshot is the scene as of the last frame taken; the avatar made now comes with
    // the next frame, the first this site gets.
    site::ToSite m;
    site::SiteWelcome& w = *m.mutable_welcome();
    w.set_snapshot(sync::serializeSnapshot(graph.snapshot()));
    p.participant = roster.join(graph, hello.name(), p.key);
    w.set_participant(p.participant);
    *w.mutable_color() = roster.color(p.participant);
    w.set_name(roster.info(p.participant).name);
    if (chunks) w.set_chunks(chunks->endpoint());
    send(p, m.SerializeAsString());
    if (voice) voice->join(p.participant);
    counters.joined++;
    say(who(p) + " joined as participant " + std::to_string(p.participant) +
        " from the snapshot of frame " + std::to_string(graph.frameNumber()));
  }

  void drain(sync::SceneGraph& graph, double now) {
    for (int budget = 100000; budget > 0; --budget) {
      zmq::message_t id, payload;
      if (!socket.recv(id, zmq::recv_flags::dontwait)) return;
      if (!id.more()) continue;  // cannot happen on a ROUTER
      (void)socket.recv(payload, zmq::recv_flags::dontwait);
      bool multipart = false;
      for (bool more = payload.more(); more;) {  // a multipart message: not a site's
        zmq::message_t rest;
        if (!socket.recv(rest, zmq::recv_flags::dontwait)) break;
        more = rest.more();
        multipart = true;
      }
      const std::string rid = id.to_string();
      counters.messages_in++;
      counters.bytes_in += payload.size();
      if (discarded.count(rid)) {
        counters.discarded++;
        continue;
      }
      auto [it, fresh] = peers.try_emplace(rid);
      Peer& p = it->second;
      if (fresh) {
        p.id = rid;
        const char* key = payload.gets("User-Id");
        p.key = key ? key : "";
        p.messages.start(opt.messages_per_s, opt.burst_s, now);
        p.bytes.start(opt.bytes_per_s, opt.burst_s, now);
        p.video.start(opt.video_cap_kbps * 1000.0 / 8.0, 1.0, now);
        p.last_seen = now;
      }
      if (p.gone) continue;
      if (!p.messages.take(1.0, now) || !p.bytes.take(double(payload.size()), now)) {
        remove(graph, rid,
               "flooding: more than " + std::to_string(int(opt.messages_per_s)) + " messages or " +
                   std::to_string(int(opt.bytes_per_s / 1024)) + " KiB a second (sustained)",
               true);
        continue;
      }
      if (multipart) {
        remove(graph, rid, "a bad message: more than one part", true);
        continue;
      }
      site::ToMaster m;
      if (auto why = parseToMaster(
              std::string_view(static_cast<const char*>(payload.data()), payload.size()), m)) {
        remove(graph, rid, "a bad message: " + *why, true);
        continue;
      }
      if (!p.participant && m.kind_case() != site::ToMaster::kHello) {
        remove(graph, rid, "a message before its hello", true);
        continue;
      }
      p.last_seen = now;
      if (m.kind_case() == site::ToMaster::kHello) {
        if (!p.participant) welcome(graph, p, m.hello());
      } else if (m.kind_case() == site::ToMaster::kBye) {
        p.gone = true;
        p.gone_reason = "it said goodbye";
      } else if (m.kind_case() == site::ToMaster::kNote) {
        site::ToSite answer;
        *answer.mutable_note() =
            applySiteNote(notes, graph, roster.info(p.participant).name, m.note());
        if (answer.note().ok())
          counters.notes++;
        else
          say(roster.info(p.participant).name + ": note refused: " + answer.note().error());
        send(p, answer.SerializeAsString());
      } else if (m.kind_case() == site::ToMaster::kSelect ||
                 m.kind_case() == site::ToMaster::kSnap) {
        if (!selections)
          selections =
              std::make_unique<SiteSelections>([this](const std::string& line) { say(line); });
        if (m.kind_case() == site::ToMaster::kSelect)
          selections->request(graph, p.participant, roster.info(p.participant).name, m.select());
        else
          selections->request(graph, p.participant, roster.info(p.participant).name, m.snap());
      } else if (m.kind_case() == site::ToMaster::kVideo) {
        video(graph, p, m.video(), now);
      } else if (m.kind_case() == site::ToMaster::kVoice) {
        counters.voice_in++;
        media::VoicePacket packet;
        if (voice &&
            !media::decodeVoicePacket(
                {reinterpret_cast<const uint8_t*>(m.voice().data()), m.voice().size()}, packet))
          voice->receive(p.participant, packet, now - voice_start);
      } else {
        roster.apply(graph, p.participant, m, now);
      }
    }
  }
};

SiteHub::SiteHub(SiteHubOptions options) : m(std::make_unique<Impl>()) {
  m->opt = std::move(options);
  if (m->opt.wall.tiles_size() > 0) m->roster.setWall(m->opt.wall);
  m->keys = readKeyFile(m->opt.key_file);
  m->allow = std::make_shared<AllowList>(m->opt.allow_list);
  m->allow_generation = m->allow->generation();
  m->zap = std::make_unique<ZapHandler>(m->context, m->allow);
  m->socket = bindSiteServer(m->context, m->keys, m->opt.endpoint, m->opt.send_queue,
                             int64_t(kMaxSiteMessageBytes), "collab::SiteHub");
  if (!m->opt.chunks_endpoint.empty()) {
    ChunkServerOptions co;
    co.endpoint = m->opt.chunks_endpoint;
    co.bytes_per_s = m->opt.chunk_bytes_per_s;
    co.total_bytes_per_s = m->opt.chunk_total_bytes_per_s;
    m->chunks = std::make_unique<ChunkServer>(m->context, m->keys, co);
  }
  if (m->opt.voice) {
    const media::VoiceSettings settings;
    const auto say_device = [impl = m.get()](const std::string& line) { impl->say(line); };
    const std::optional<std::string> in_device = media::alsaDeviceOf(m->opt.audio_in);
    const std::optional<std::string> out_device = media::alsaDeviceOf(m->opt.audio_out);
    if (in_device) {
      m->wall_microphone =
          std::make_unique<media::AlsaMicrophone>(*in_device, settings.frameSamples(), say_device);
      m->say("voice: the wall room's microphone: " + m->wall_microphone->pcm().describe());
    }
    if (out_device) {
      // 150 ms queued on the device: the master's frame loop (15-30 frames a second, slower
      // when a node is late) must not let it run dry between two frames.
      m->wall_speaker =
          std::make_unique<media::AlsaSpeaker>(*out_device, settings.frameSamples(), 0.15, say_device);
      m->say("voice: the wall room's speakers: " + m->wall_speaker->pcm().describe());
    }
    m->voice = std::make_unique<media::VoiceBridge>(settings, m->opt.audio_in.empty() || in_device
                                                           ? std::vector<float>{}
                                                           : media::readVoiceWav(m->opt.audio_in));
    m->voice_start = seconds(Clock::now());
  }
}

SiteHub::~SiteHub() {
  if (!m) return;
  m->chunks.reset();
  m->socket.close();
  m->zap.reset();
}

void SiteHub::setAnnotations(annotate::AnnotationScene* notes) {
  m->notes = notes;
}

std::string SiteHub::endpoint() const {
  return m->socket.get(zmq::sockopt::last_endpoint);
}

std::string SiteHub::chunksEndpoint() const {
  return m->chunks ? m->chunks->endpoint() : std::string();
}

void SiteHub::beforeFrame(sync::SceneGraph& graph, uint64_t, double) {
  const double now = seconds(Clock::now());
  if (now - m->last_reload > 0.5) {
    m->last_reload = now;
    if (auto why = m->allow->reload()) m->say("allow list " + m->opt.allow_list + ": " + *why);
    if (m->allow->generation() != m->allow_generation) {
      m->allow_generation = m->allow->generation();
      std::vector<std::string> removed;
      for (const auto& [rid, p] : m->peers)
        if (!m->allow->find(p.key)) removed.push_back(rid);
      for (const std::string& rid : removed)
        m->remove(graph, rid, "its key was taken off the allow list", true);
    }
    std::erase_if(m->discarded, [&](const auto& d) { return now - d.second > 60.0; });
    if (m->chunks) {  // the chunk server serves what the scene's models name, nothing else
      std::vector<std::string> stores;
      for (const auto id : graph.ids()) {
        const scene::SceneNode& n = graph.node(id);
        if (n.kind() != scene::SceneNode::MODEL) continue;
        stores.push_back(n.model().store());
        // A see-through mesh is drawn from its sampled points (MESH#points): those too.
        const std::string key = render::SceneDrawList::storeKey(graph, id);
        if (key != n.model().store()) stores.push_back(key);
      }
      m->chunks->setStores(std::move(stores));
    }
  }
  m->drain(graph, now);
  std::vector<std::pair<std::string, std::string>> gone;
  for (const auto& [rid, p] : m->peers) {
    if (p.gone) {
      gone.emplace_back(rid, p.gone_reason);
    } else if (now - p.last_seen > m->opt.silent_timeout_s) {
      char why[64];
      std::snprintf(why, sizeof why, "silent for %.1f s", now - p.last_seen);
      gone.emplace_back(rid, why);
    }
  }
  for (const auto& [rid, why] : gone) m->remove(graph, rid, why, false);
  std::vector<uint32_t> stopped;  // sites whose video stopped: their insets go
  for (const auto& [participant, inset] : m->insets)
    if (now - inset.last > m->opt.video_timeout_s) stopped.push_back(participant);
  for (const uint32_t participant : stopped) {
    m->say("participant " + std::to_string(participant) + " stopped its video: its inset goes");
    m->removeInset(graph, participant);
  }
  m->roster.animate(graph, now);
  if (m->selections) m->selections->collect(graph);
  if (m->voice) {
    std::map<uint32_t, Peer*> by_participant;
    for (auto& [rid, p] : m->peers)
      if (p.participant && !p.gone) by_participant[p.participant] = &p;
    site::ToSite out;
    const double voice_now = now - m->voice_start;
    if (m->wall_microphone)
      m->wall_microphone->pump(voice_now,
                               [&](std::span<const float> frame) { m->voice->hearWall(frame); });
    m->voice->advance(voice_now, [&](uint32_t to, const std::vector<uint8_t>& bytes) {
      auto it = by_participant.find(to);
      if (it == by_participant.end()) return;
      out.set_voice(bytes.data(), bytes.size());
      if (m->send(*it->second, out.SerializeAsString())) m->counters.voice_out++;
    });
    if (m->wall_speaker) {
      // The mix is made on the session's clock and played on the device's: a queue between
      // them, cut to kVoiceMaxCatchUp_s (a slower device loses the oldest; a faster one plays
      // silence while the queue is empty).
      const std::vector<float> room = m->voice->takeRoom();
      auto& q = m->room_queue;
      q.insert(q.end(), room.begin(), room.end());
      const size_t most = size_t(media::kVoiceMaxCatchUp_s * media::kVoiceRate);
      if (q.size() > most) q.erase(q.begin(), q.end() - ptrdiff_t(most));
      m->wall_speaker->pump(voice_now, [&](double, std::span<float> frame) {
        const size_t have = std::min(frame.size(), q.size());
        std::copy_n(q.begin(), have, frame.begin());
        std::fill(frame.begin() + ptrdiff_t(have), frame.end(), 0.0f);
        q.erase(q.begin(), q.begin() + ptrdiff_t(have));
      });
    }
  }
}

void SiteHub::afterFrame(const sync::SceneGraph& graph, const std::string& bytes) {
  site::ToSite frame;
  frame.set_frame(bytes);
  const std::string frame_bytes = frame.SerializeAsString();
  std::string snapshot_bytes;
  for (auto& [rid, s] : m->peers) {
    if (!s.participant || s.gone) continue;
    if (s.behind) {
      if (snapshot_bytes.empty()) {
        site::ToSite snap;
        snap.set_snapshot(sync::serializeSnapshot(graph.snapshot()));
        snapshot_bytes = snap.SerializeAsString();
      }
      if (m->send(s, snapshot_bytes)) {
        s.behind = false;
        m->counters.snapshots_resent++;
      }
      continue;
    }
    if (!m->send(s, frame_bytes) && !s.gone) s.behind = true;
  }
}

void SiteHub::takeMedia(std::vector<std::string>& out) {
  for (std::string& chunk : m->media) out.push_back(std::move(chunk));
  m->media.clear();
  m->media_bytes = 0;
}

void SiteHub::end(const std::string& reason) {
  site::ToSite q;
  q.mutable_quit()->set_reason(reason);
  const std::string bytes = q.SerializeAsString();
  for (auto& [rid, p] : m->peers)
    if (p.participant) m->send(p, bytes);
  if (m->voice) {
    m->say("voice: " + std::to_string(m->counters.voice_in) + " packets from sites, " +
           std::to_string(m->counters.voice_out) + " to them");
    if (!m->opt.audio_out.empty() && !m->wall_speaker) {
      try {
        media::writeWav(m->opt.audio_out, m->voice->room());
        m->say("the wall room's audio: " + m->opt.audio_out);
      } catch (const media::WavError& e) {
        std::fprintf(stderr, "tessera-master: %s\n", e.what());
      }
    }
  }
  if (m->counters.video_in > 0) {
    char line[200];
    std::snprintf(line, sizeof line,
                  "video: %llu chunks from sites (%llu dropped over the cap), %llu to the nodes, "
                  "%llu to other sites",
                  (unsigned long long)m->counters.video_in,
                  (unsigned long long)m->counters.video_dropped,
                  (unsigned long long)m->counters.video_to_nodes,
                  (unsigned long long)m->counters.video_to_sites);
    m->say(line);
  }
  if (m->counters.notes > 0)
    m->say("annotations: " + std::to_string(m->counters.notes) + " edits from sites committed");
  const SiteHubCounters& c = m->counters;
  char line[320];
  std::snprintf(line, sizeof line,
                "%llu joined, %llu left, %llu dropped, %llu refused; received %llu bytes in %llu "
                "messages, sent %llu bytes in %llu messages (%llu snapshots to sites that fell "
                "behind)",
                (unsigned long long)c.joined, (unsigned long long)c.left,
                (unsigned long long)c.dropped, (unsigned long long)c.refused,
                (unsigned long long)c.bytes_in, (unsigned long long)c.messages_in,
                (unsigned long long)c.bytes_out, (unsigned long long)c.messages_out,
                (unsigned long long)c.snapshots_resent);
  m->say(line);
  if (m->chunks) {
    const ChunkServerCounters k = m->chunks->counters();
    std::snprintf(line, sizeof line,
                  "chunk server: %llu requests, %llu replies (%llu range bytes), %llu refused, "
                  "%llu discarded (over the request rate), %llu withdrawn by their site",
                  (unsigned long long)k.requests, (unsigned long long)k.replies,
                  (unsigned long long)k.bytes_out, (unsigned long long)k.refused,
                  (unsigned long long)k.discarded, (unsigned long long)k.cancelled);
    m->say(line);
  }
}

std::vector<SiteInfo> SiteHub::sites() const {
  return m->roster.sites();
}

SiteHubCounters SiteHub::counters() const {
  SiteHubCounters c = m->counters;
  if (m->chunks) {
    const ChunkServerCounters k = m->chunks->counters();
    c.chunk_requests = k.requests;
    c.chunk_refused = k.refused;
    c.chunk_bytes_out = k.bytes_out;
  }
  return c;
}

}  // namespace tessera::collab
