// bench/voice: the voice path on this machine, without a sound device.
//
//  1. Mouth-to-ear latency against network jitter: a synthetic voice through the real Opus
//     encoder, a simulated network (20 ms fixed delay plus exponential jitter of 0..40 ms mean),
//     the adaptive jitter buffer and a 10 ms playout clock. Each played sample is traced back to
//     the sent sample it carries (the buffer's record of sender timestamps, less the codec's
//     lookahead): latency = play time - capture time. Reported with the network's fixed delay
//     taken out (what loopback would show), beside the buffer's target and measured delay and
//     the RFC 3550 jitter, for 20 ms and 10 ms frames. The sound card's own output buffer (one
//     or two device periods) is not in it.
//  2. Encode and decode CPU per stream (thread CPU time per second of audio) at complexities
//     5, 9 (the default) and 10.
//  3. Quality against packet loss 0..20% (10 ms mean jitter): SNR against the clean path (the
//     same codec without loss or jitter) and against the sent signal, the share of concealed
//     frames and of those recovered by FEC, with in-band FEC on and off, averaged over seeds.
//     The signals: the synthetic voice and, when espeak-ng is installed, a spoken sentence.
//
//   voice [--seconds S] [--seeds N] [--out DIR]
//
// Writes DIR/voice_latency.csv, DIR/voice_cpu.csv, DIR/voice_quality.csv and DIR/voice.png.
#include <CLI/CLI.hpp>

#include <time.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <tessera/media/voice_codec.h>
#include <tessera/core/cli.h>

#include "../tests/support/voice_path.h"
#include "bench_stats.h"

namespace {

using tessera::bench::percentile;
using tessera::bench::threadCpuSeconds;

namespace fs = std::filesystem;
using namespace tessera;
using test::NetworkModel;
using test::VoicePath;
using test::VoicePathOptions;

/// Per played sample that carries a sent one (decoded, FEC or concealed frames), after the
/// first second: play time - capture time, seconds. The playout clock starts at 0.0037 s and
/// plays output sample o at 0.0037 + o / rate (runVoicePath's device).
std::vector<double> latencies(const VoicePath& path) {
  std::vector<double> out;
  for (const media::PlayedFrame& f : path.history) {
    if (f.kind != media::PlayedFrame::Kind::kDecoded) continue;
    const double captured =
        (double(uint32_t(f.timestamp - 0xFFFF0000u)) - path.lookahead) / media::kVoiceRate;
    if (captured < 1.0) continue;
    out.push_back(0.0037 + double(f.output) / media::kVoiceRate - captured);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  return tessera::cli::runMain("voice", [&]() -> int {
    CLI::App app{"bench/voice: voice latency, codec CPU and quality against packet loss"};
    double seconds = 10.0;
    int seeds = 3;
    std::string out = std::string(TESSERA_BENCH_RESULTS_DIR);
    app.add_option("--seconds", seconds, "Seconds of synthetic voice per run")
        ->check(tessera::cli::finiteRange(3.0, 600.0))
        ->capture_default_str();
    app.add_option("--seeds", seeds, "Network seeds averaged per loss rate")
        ->check(CLI::Range(1, 50))
        ->capture_default_str();
    app.add_option("--out", out, "Output folder")->capture_default_str();
    if (const auto code = tessera::cli::parse(app, argc, argv, "voice")) return *code;
    const fs::path res(out);
    fs::create_directories(res);
    const std::vector<float> voice = test::syntheticSpeech(seconds, 7);

    // 1. Latency against jitter.
    std::ofstream lat(res / "voice_latency.csv");
    lat << "frame_ms,jitter_mean_ms,rfc3550_jitter_ms,target_ms,buffer_delay_median_ms,"
           "mouth_to_ear_median_ms,mouth_to_ear_p95_ms,concealed_percent\n";
    std::printf("== mouth-to-ear on loopback (the network's fixed 20 ms taken out)\n");
    for (int frame_ms : {20, 10}) {
      for (double jitter : {0.0, 2.0, 5.0, 10.0, 20.0, 40.0}) {
        VoicePathOptions o;
        o.codec.frame_ms = frame_ms;
        NetworkModel net;
        net.jitter_ms = jitter;
        net.seed = 3;
        const VoicePath p = runVoicePath(voice, net, o);
        std::vector<double> l = latencies(p);
        for (double& v : l) v = (v - net.base_ms / 1000) * 1000;
        std::vector<double> delays(p.delays_s.begin() + ptrdiff_t(p.delays_s.size() / 10),
                                   p.delays_s.end());
        const double conc = 100.0 * double(p.stats.concealed) / double(p.stats.frames());
        char row[256];
        std::snprintf(row, sizeof row, "%d,%.0f,%.2f,%.1f,%.1f,%.1f,%.1f,%.2f", frame_ms, jitter,
                      p.stats.jitter_s * 1e3, p.stats.target_s * 1e3, percentile(delays, 0.5) * 1e3,
                      percentile(l, 0.5), percentile(l, 0.95), conc);
        lat << row << "\n";
        std::printf(
            "frame %2d ms, jitter mean %4.0f ms (RFC 3550 J %5.2f ms): target %5.1f ms, "
            "buffer %5.1f ms, mouth-to-ear median %5.1f ms, p95 %5.1f ms, concealed "
            "%.2f%%\n",
            frame_ms, jitter, p.stats.jitter_s * 1e3, p.stats.target_s * 1e3,
            percentile(delays, 0.5) * 1e3, percentile(l, 0.5), percentile(l, 0.95), conc);
      }
    }
    lat.close();

    // 2. CPU per stream.
    std::ofstream cpu(res / "voice_cpu.csv");
    cpu << "complexity,encode_ms_per_s,decode_ms_per_s,kbit_per_s\n";
    std::printf("== codec CPU per stream (one core of this machine)\n");
    for (int complexity : {5, 9, 10}) {
      media::VoiceSettings s;
      s.complexity = complexity;
      s.dtx = false;
      media::VoiceEncoder enc(s);
      media::VoiceDecoder dec;
      std::vector<std::vector<uint8_t>> packets;
      const size_t n = size_t(s.frameSamples());
      size_t bytes = 0;
      double t0 = threadCpuSeconds();
      for (int rep = 0; rep < 3; ++rep)
        for (size_t at = 0; at + n <= voice.size(); at += n) {
          std::vector<uint8_t> p;
          enc.encode(std::span<const float>(voice).subspan(at, n), p);
          bytes += p.size();
          packets.push_back(std::move(p));
        }
      const double encode_s = threadCpuSeconds() - t0;
      std::vector<float> frame(n);
      t0 = threadCpuSeconds();
      for (const auto& p : packets) dec.decode(p, frame);
      const double decode_s = threadCpuSeconds() - t0;
      const double audio_s = double(packets.size() * n) / media::kVoiceRate;
      const double kbps = double(bytes) * 8 / audio_s / 1000;
      cpu << complexity << "," << encode_s / audio_s * 1000 << "," << decode_s / audio_s * 1000
          << "," << kbps << "\n";
      std::printf(
          "complexity %2d: encode %.2f ms, decode %.2f ms CPU per second of audio "
          "(%.2f%% and %.2f%% of a core), %.1f kbit/s\n",
          complexity, encode_s / audio_s * 1000, decode_s / audio_s * 1000,
          encode_s / audio_s * 100, decode_s / audio_s * 100, kbps);
    }
    cpu.close();

    // 3. Quality against loss.
    std::vector<std::pair<std::string, std::vector<float>>> signals{{"synthetic", voice}};
    if (auto speech = test::espeakSpeech(
            res / "voice_sentence.wav",
            "The north wall of the chapel shows the oldest layer of plaster, under the later "
            "paintings. Look at the crack above the window, near the left corner."))
      signals.emplace_back("espeak", *speech);
    else
      std::printf("(espeak-ng not installed: the synthetic voice only)\n");
    std::ofstream qual(res / "voice_quality.csv");
    // fec_percent: frames taken from the next packet's FEC data (with FEC off the stream has
    // none, and libopus conceals them instead: the same frames, the same count).
    qual << "signal,fec,loss_percent,snr_clean_db,snr_sent_db,concealed_percent,fec_percent\n";
    std::printf("== quality against loss (10 ms mean jitter, %d seeds)\n", seeds);
    for (const auto& [name, x] : signals) {
      for (bool fec : {true, false}) {
        VoicePathOptions o;
        o.codec.fec = fec;
        const VoicePath clean = runVoicePath(x, NetworkModel{}, o);
        for (int loss = 0; loss <= 20; loss += 2) {
          test::PathQuality mean;
          for (int seed = 0; seed < seeds; ++seed) {
            NetworkModel net;
            net.loss = loss / 100.0;
            net.jitter_ms = 10;
            net.seed = uint32_t(100 + seed);
            const test::PathQuality q = test::pathQuality(x, clean, runVoicePath(x, net, o));
            mean.snr_clean += q.snr_clean / seeds;
            mean.snr_sent += q.snr_sent / seeds;
            mean.concealed += q.concealed / seeds;
            mean.fec += q.fec / seeds;
          }
          char row[256];
          std::snprintf(row, sizeof row, "%s,%s,%d,%.2f,%.2f,%.2f,%.2f", name.c_str(),
                        fec ? "on" : "off", loss, mean.snr_clean, mean.snr_sent,
                        mean.concealed * 100, mean.fec * 100);
          qual << row << "\n";
          std::printf(
              "%-9s FEC %-3s loss %2d%%: SNR %5.1f dB against the clean path, %5.1f dB "
              "against the sent signal; concealed %5.2f%% (from the next packet %5.2f%%)\n",
              name.c_str(), fec ? "on" : "off", loss, mean.snr_clean, mean.snr_sent,
              mean.concealed * 100, mean.fec * 100);
        }
      }
    }
    qual.close();

    // The chart.
    const std::string q = (res / "voice_quality.csv").string();
    const std::string l = (res / "voice_latency.csv").string();
    std::ofstream gp(res / "voice.gp");
    gp << "set terminal pngcairo noenhanced size 1400,500 font ',10'\n"
       << "set output '" << (res / "voice.png").string() << "'\n"
       << "set datafile separator ','\nset multiplot layout 1,2\nset grid\n"
       << "set title 'Voice quality against packet loss (Opus 32 kb/s, 20 ms, 10 ms mean "
          "jitter)'\nset xlabel 'packet loss (%)'\nset ylabel 'SNR against the clean path (dB)'\n"
       << "set y2label 'concealed frames (%)'\nset y2tics\nset ytics nomirror\nset key top right\n"
       << "plot '" << q
       << "' skip 1 using (strcol(1) eq 'synthetic' && strcol(2) eq 'on' ? $3 : 1/0):4 w lp pt 7 "
          "lc "
          "rgb '#1f77b4' title 'synthetic voice, FEC on', \\\n"
       << "  '' skip 1 using (strcol(1) eq 'synthetic' && strcol(2) eq 'off' ? $3 : 1/0):4 w lp pt "
          "6 dt 2 lc rgb "
          "'#1f77b4' title 'synthetic voice, FEC off', \\\n"
       << "  '' skip 1 using (strcol(1) eq 'espeak' && strcol(2) eq 'on' ? $3 : 1/0):4 w lp pt 5 "
          "lc rgb '#d62728' "
          "title 'espeak-ng sentence, FEC on', \\\n"
       << "  '' skip 1 using (strcol(1) eq 'espeak' && strcol(2) eq 'off' ? $3 : 1/0):4 w lp pt 4 "
          "dt 2 lc rgb "
          "'#d62728' title 'espeak-ng sentence, FEC off', \\\n"
       << "  '' skip 1 using (strcol(1) eq 'synthetic' && strcol(2) eq 'on' ? $3 : 1/0):6 axes "
          "x1y2 w l lw 2 lc rgb "
          "'#2ca02c' title 'concealed (synthetic, FEC on), right axis'\n"
       << "unset y2label\nunset y2tics\nset ytics mirror\n"
       << "set title 'Mouth-to-ear on loopback against network jitter (20 ms fixed network delay "
          "taken out)'\nset xlabel 'mean network jitter (ms, exponential)'\nset ylabel 'ms'\n"
       << "set key top left\n"
       << "plot '" << l
       << "' skip 1 using ($1 == 20 ? $2 : 1/0):6 w lp pt 7 lc rgb '#1f77b4' "
          "title 'mouth-to-ear median, 20 ms frames', \\\n"
       << "  '' skip 1 using ($1 == 20 ? $2 : 1/0):7 w lp pt 6 dt 2 lc rgb '#1f77b4' title "
          "'p95, 20 ms frames', \\\n"
       << "  '' skip 1 using ($1 == 10 ? $2 : 1/0):6 w lp pt 5 lc rgb '#ff7f0e' title "
          "'mouth-to-ear median, 10 ms frames', \\\n"
       << "  '' skip 1 using ($1 == 20 ? $2 : 1/0):5 w lp pt 9 lc rgb '#2ca02c' title "
          "'jitter buffer delay, 20 ms frames', \\\n"
       << "  '' skip 1 using ($1 == 20 ? $2 : 1/0):($5 + 60) w l dt 3 lw 2 lc rgb '#d62728' "
          "title 'goal: 60 ms + the jitter buffer'\n"
       << "unset multiplot\n";
    gp.close();
    std::string gnuplot = TESSERA_GNUPLOT;
    if (gnuplot.empty()) gnuplot = "gnuplot";
    if (std::system(("'" + gnuplot + "' '" + (res / "voice.gp").string() + "'").c_str()))
      std::cerr << "voice: gnuplot failed; the CSVs are still there\n";
    else
      std::cerr << "chart: " << (res / "voice.png").string() << "\n";
    return 0;
  });
}
