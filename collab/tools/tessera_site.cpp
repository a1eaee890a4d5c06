// tessera-site: a remote site of a Tessera session. Parses the command line and runs
// collab::SiteSession (site_session.h); `keygen` makes the CURVE key pairs of sites and masters.
//   tessera-site keygen -o site.key        # prints the public key for the master's allow list
//   tessera-site --master tcp://HOST:7401 --master-key MASTER_PUBLIC_KEY|FILE --name "Kyoto lab"
//                --key site.key --headless -o DIR [--script PATH.json] [--no-render]
//                [--cache DIR] [--remote-stores]
//                [--audio-in WAV|alsa:DEVICE] [--audio-out WAV|alsa:DEVICE]
//                [--video test|FILE|/dev/videoN [--video-size 640x480] [--video-kbps N]]
#include <CLI/CLI.hpp>

#include <cstdio>

#include <tessera/collab/curve.h>
#include <tessera/collab/site_messages.h>
#include <tessera/collab/site_session.h>
#include <tessera/core/cli.h>
#include <tessera/media/voice_alsa.h>

namespace {

using namespace tessera;

int run(int argc, char** argv) {
  CLI::App app{
      "tessera-site: join a Tessera session from another place: see the scene from your own "
      "viewpoint, appear on the wall as an avatar, draw on the model, lead or follow the view"};
  app.require_subcommand(0, 1);
  std::string keygen_out;
  CLI::App* keygen =
      app.add_subcommand("keygen",
                         "Write a new CURVE key pair (mode 0600) and print its public key (for the "
                         "master's --allow list, or for the sites' --master-key)");
  keygen->add_option("-o,--output", keygen_out, "The key file to write (never overwritten)")
      ->required();

  collab::SiteSessionOptions o;
  std::string key_file, master_key;
  bool headless = false, no_render = false;
  app.add_option("--master", o.client.master, "The master's site endpoint, tcp://HOST:7401");
  app.add_option("--master-key", master_key,
                 "The master's public key (40 Z85 characters), or a file holding it");
  app.add_option("--name", o.client.name, "Shown on this site's avatar (1..64 bytes of UTF-8)");
  app.add_option("--key", key_file, "This site's key pair (tessera-site keygen; mode 0600)");
  std::string size = "960x640";
  bool window = false;
  app.add_flag("--window", window,
               "A window: left button navigates (one button: click a target, drag to orbit, "
               "right-hand bar forward/back, wheel zooms), right-button drag draws on the model; "
               "keys L lead, R release, F follow, U undo, C clear, P picture, Esc quit");
  app.add_option("--size", size, "--window: its size in pixels, WxH")->capture_default_str();
  app.add_flag("--headless", headless, "No window: play --script, screenshots to -o");
  app.add_option("-o,--out-dir", o.out_dir, "Screenshots and strokes.csv (headless)")
      ->capture_default_str();
  app.add_option("--script", o.script,
                 "Headless: what to do at which frame (JSON: site.proto SiteScript)");
  app.add_flag("--no-render", no_render,
               "Send poses and requests without rendering (load tests of the master)");
  app.add_option("--join-timeout", o.join_timeout_s, "Seconds to wait for the master's welcome")
      ->check(cli::finiteRange(0.1, 3600.0))
      ->capture_default_str();
  app.add_flag("--remote-stores", o.remote_stores,
               "Take every store from the master's chunk server (tessera-master --chunks), even "
               "where this host has a file at the scene's path (without it: only stores not here)");
  app.add_option("--cache", o.cache_dir,
                 "Keep the chunks fetched from the master in this folder between sessions");
  app.add_option("--cache-mb", o.cache_mb,
                 "The --cache folder's bound over all stores, MB: past it the ranges used least "
                 "recently are removed")
      ->check(cli::finiteRange(0.01, 1e9))
      ->capture_default_str();
  app.add_option("--chunk-timeout", o.chunk_timeout_s,
                 "Seconds a chunk request may go unanswered before it is sent again (once)")
      ->check(cli::finiteRange(0.1, 3600.0))
      ->capture_default_str();
  app.add_option("--withdraw-after", o.withdraw_after_frames,
                 "Frames in a row that may not want a chunk requested from the master before its "
                 "request is withdrawn (the view moved on); 0: every request waits for its answer")
      ->check(cli::integerRange<uint32_t>(0, 1000000))
      ->capture_default_str();
  app.add_option("--audio-in", o.audio_in,
                 "Voice (the master runs --voice): this site's microphone, a WAV file (16-bit "
                 "PCM, any rate, mono or stereo) sent from the join on, or a sound device "
                 "through ALSA: alsa:default, alsa:hw:0,0, ...");
  app.add_option("--audio-out", o.audio_out,
                 "Voice: what this site hears (the wall's microphone and the other sites), "
                 "written as a 48 kHz WAV file when the session ends, or played on a sound "
                 "device through ALSA: alsa:default, alsa:hw:0,0, ...");
  std::string video_size = "640x480";
  app.add_option("--video", o.video,
                 "Send video to the wall and the other sites (an inset beside this site's "
                 "avatar): test (a test pattern with its frame number and clock burned in), a "
                 "video file FFmpeg reads (looped), or a V4L2 camera /dev/videoN");
  app.add_option("--video-size", video_size, "--video: the picture's size, WxH (even)")
      ->capture_default_str();
  app.add_option("--video-kbps", o.video_settings.kbps,
                 "--video: H.264 bitrate cap, kbit/s (the master's --video-cap must allow it)")
      ->check(CLI::Range(50, 50000))
      ->capture_default_str();
  app.add_option("--video-fps", o.video_settings.fps, "--video: pictures per second")
      ->check(cli::finiteRange(1, 120))
      ->capture_default_str();
  if (const auto code = cli::parse(app, argc, argv, "tessera-site")) return *code;
  {
    const cli::Size vs = cli::parseSize(video_size, "--video-size", media::kMaxVideoSide);
    o.video_settings.width = int(vs.width);
    o.video_settings.height = int(vs.height);
    if (auto why = o.video_settings.problem()) throw cli::UsageError("--video-size: " + *why);
  }

  if (keygen->parsed()) {
    const collab::KeyPair keys = collab::generateKeyPair();
    collab::writeKeyFile(keygen_out, keys);
    std::printf("%s\n", keys.public_key.c_str());
    std::fprintf(stderr, "tessera-site: wrote %s (mode 0600); its public key is above\n",
                 keygen_out.c_str());
    return 0;
  }
  for (const auto& [value, option] :
       {std::pair{&o.client.master, "--master"}, std::pair{&master_key, "--master-key"},
        std::pair{&o.client.name, "--name"}, std::pair{&key_file, "--key"}}) {
    if (value->empty()) throw cli::UsageError(std::string(option) + " is required");
  }
  if (headless == window)
    throw cli::UsageError("give one of --window (a person at the site) and --headless (a script)");
  if (window && no_render) throw cli::UsageError("--window draws: it cannot go with --no-render");
  const cli::Size wh = cli::parseSize(size, "--size", 8192);
  if (wh.width < 16 || wh.height < 16) throw cli::UsageError("--size " + size + ": at least 16x16");
  o.window = window;
  o.window_width = wh.width;
  o.window_height = wh.height;
  if (auto why = collab::checkName(o.client.name, "--name")) throw cli::UsageError(*why);
  try {
    o.client.master_key = collab::readPublicKey(master_key, "--master-key");
    o.client.keys = collab::readKeyFile(key_file);
  } catch (const collab::KeyError& e) {
    throw cli::UsageError(e.what());
  }
  o.render = !no_render;
  // Written when the session ends, so refused now when it could not be.
  if (!o.audio_out.empty() && !media::alsaDeviceOf(o.audio_out))
    cli::refuseUnwritable(o.audio_out, "--audio-out");
  collab::SiteSession session(o);
  return session.run();
}

}  // namespace

int main(int argc, char** argv) {
  // Ctrl-C, SIGTERM: the site says goodbye and writes what it recorded, as when its script ends.
  tessera::cli::catchStopSignals();
  return tessera::cli::runMain("tessera-site", [&] { return run(argc, argv); });
}
