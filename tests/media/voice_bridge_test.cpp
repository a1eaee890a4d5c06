// The voice ends of the site link (media/voice_bridge.h) in one process: three voices (the
// wall's microphone and two sites, each a tone of its own pitch) through stations, a simulated
// link with delay and jitter both ways, and the master's bridge. Who hears whom is read from
// the outputs' spectra (Goertzel): the room hears the sites, each site the others, nobody itself.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <tessera/media/voice_bridge.h>

#include "../support/voice_path.h"

namespace {

using namespace tessera::media;

using tessera::test::db;
using tessera::test::power;
using tessera::test::talking;

struct InFlight {
  double at;
  uint32_t to;  ///< 0: the bridge; else the station of that participant
  uint32_t from;
  std::vector<uint8_t> bytes;
};

TEST(VoiceBridge, TheRoomHearsTheSitesAndEachSiteEveryoneButItself) {
  const double seconds = 6;
  VoiceBridge bridge(VoiceSettings{}, talking(300, seconds));
  std::map<uint32_t, VoiceStation> stations;
  stations.emplace(1, VoiceStation(VoiceSettings{}, talking(500, seconds)));
  stations.emplace(2, VoiceStation(VoiceSettings{}, talking(700, seconds)));
  bridge.join(1);
  bridge.join(2);
  std::mt19937 rng(2);
  std::exponential_distribution<double> jitter(1 / 0.008);
  std::vector<InFlight> flight;
  size_t to_sites = 0;
  // Both ends run from loops at 30 frames a second, the stations' clocks 5 ms after the bridge's.
  for (double t = 0; t < seconds + 0.5; t += 1.0 / 30) {
    std::stable_sort(flight.begin(), flight.end(),
                     [](const InFlight& a, const InFlight& b) { return a.at < b.at; });
    while (!flight.empty() && flight.front().at <= t) {
      InFlight f = std::move(flight.front());
      flight.erase(flight.begin());
      if (f.to == 0) {
        VoicePacket p;
        ASSERT_EQ(decodeVoicePacket(f.bytes, p), std::nullopt);
        bridge.receive(f.from, p, t);
      } else {
        ASSERT_EQ(stations.at(f.to).receive(f.bytes, t - 0.005), std::nullopt);
      }
    }
    for (auto& [id, station] : stations)
      station.advance(t - 0.005, [&, id = id](std::vector<uint8_t> bytes) {
        flight.push_back({t + 0.02 + jitter(rng), 0, id, std::move(bytes)});
      });
    bridge.advance(t, [&](uint32_t to, const std::vector<uint8_t>& bytes) {
      ++to_sites;
      flight.push_back({t + 0.02 + jitter(rng), to, 0, bytes});
    });
  }
  EXPECT_GT(to_sites, 200u);
  const size_t from = 48000, to = size_t((seconds - 0.5) * 48000);
  const auto& room = bridge.room();
  const auto& a = stations.at(1).speaker();
  const auto& b = stations.at(2).speaker();
  std::printf("room: 300 Hz %.0f dB, 500 Hz %.0f dB, 700 Hz %.0f dB\n",
              db(power(room, 300, from, to)), db(power(room, 500, from, to)),
              db(power(room, 700, from, to)));
  std::printf("site 1: 300 Hz %.0f dB, 500 Hz %.0f dB, 700 Hz %.0f dB\n",
              db(power(a, 300, from, to)), db(power(a, 500, from, to)),
              db(power(a, 700, from, to)));
  std::printf("site 2: 300 Hz %.0f dB, 500 Hz %.0f dB, 700 Hz %.0f dB\n",
              db(power(b, 300, from, to)), db(power(b, 500, from, to)),
              db(power(b, 700, from, to)));
  // Heard: within 10 dB of the others heard; not heard: 30 dB below.
  const auto hears = [&](const std::vector<float>& x, double yes1, double yes2, double no) {
    const double p1 = db(power(x, yes1, from, to)), p2 = db(power(x, yes2, from, to));
    EXPECT_NEAR(p1, p2, 10);
    EXPECT_LT(db(power(x, no, from, to)), std::min(p1, p2) - 30);
    EXPECT_GT(std::min(p1, p2), -40);  // a tone of 0.25 peak is about -15 dB
  };
  {
    SCOPED_TRACE("the room");
    hears(room, 500, 700, 300);
  }
  {
    SCOPED_TRACE("site 1");
    hears(a, 300, 700, 500);
  }
  {
    SCOPED_TRACE("site 2");
    hears(b, 300, 500, 700);
  }
  EXPECT_LT(double(bridge.stats(1)->concealed), 0.05 * double(bridge.stats(1)->frames()));
  EXPECT_LT(double(stations.at(1).stats().concealed),
            0.05 * double(stations.at(1).stats().frames()));
}

TEST(VoiceBridge, NobodyTalkingSendsNothingAndALeaverGetsNothing) {
  VoiceBridge bridge(VoiceSettings{}, {});
  bridge.join(1);
  bridge.join(2);
  size_t sent = 0;
  for (double t = 0; t < 2; t += 0.03) bridge.advance(t, [&](uint32_t, const auto&) { ++sent; });
  EXPECT_EQ(sent, 0u);
  EXPECT_NEAR(double(bridge.room().size()), 2 * 48000, 960);
  // Site 1 talks, then leaves: site 2 hears it; nothing goes to 1, nor after it left to anyone.
  VoiceStation one(VoiceSettings{}, tessera::test::tone(440, 1));
  std::map<uint32_t, size_t> to;
  for (double t = 2; t < 3; t += 0.02) {
    one.advance(t - 2, [&](std::vector<uint8_t> bytes) {
      VoicePacket p;
      ASSERT_EQ(decodeVoicePacket(bytes, p), std::nullopt);
      bridge.receive(1, p, t);
    });
    bridge.advance(t, [&](uint32_t id, const auto&) { ++to[id]; });
  }
  EXPECT_GT(to[2], 30u);
  EXPECT_EQ(to[1], 0u);
  bridge.leave(1);
  to.clear();
  for (double t = 3; t < 4; t += 0.02)
    bridge.advance(t, [&](uint32_t id, const auto&) { ++to[id]; });
  EXPECT_LE(to[2], 3u);  // the tail of its last words
  EXPECT_EQ(bridge.stats(1), nullptr);
}

TEST(VoiceBridge, AStalledLoopSkipsAheadInsteadOfBursting) {
  VoiceStation station(VoiceSettings{}, tessera::test::tone(440, 5));
  size_t packets = 0;
  station.advance(0.1, [&](std::vector<uint8_t>) { ++packets; });
  EXPECT_EQ(packets, 5u);
  station.advance(3.1, [&](std::vector<uint8_t>) { ++packets; });  // a 3 s stall
  EXPECT_EQ(packets, 5u + size_t(kVoiceMaxCatchUp_s / 0.02));
  EXPECT_NEAR(double(station.speaker().size()), 3.1 * 48000, 480);
}

}  // namespace
