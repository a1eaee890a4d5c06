// collab/curve.h over real sockets on 127.0.0.1: the CURVE server (a ROUTER with curveServer()
// and a ZapHandler, echoing every message) runs in a forked child, so every client below is a
// separate connection across a process boundary. Every wait has a deadline; tests end by
// themselves.
#include <tessera/collab/curve.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <functional>
#include <mutex>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "../support/temp_dir.h"

namespace tessera::collab {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using test::TempDir;

constexpr auto kNothingWithin = 1500ms;  // how long a refused client waits for a reply
constexpr auto kReplyWithin = 10s;       // an admitted client's reply comes well before this

std::string readText(const std::filesystem::path& p) {
  const std::vector<uint8_t> bytes = test::readBytes(p);
  return {bytes.begin(), bytes.end()};
}

size_t countOf(const std::string& haystack, const std::string& needle) {
  size_t n = 0;
  for (size_t at = haystack.find(needle); at != std::string::npos;
       at = haystack.find(needle, at + 1))
    ++n;
  return n;
}

/// Writes an allow list with mode 0644 whatever the umask (group-writable lists are refused).
void writeAllowList(const std::filesystem::path& p, const std::string& text) {
  test::writeText(p, text);
  ::chmod(p.c_str(), 0644);
}

/// Rewrites a file and moves its modification time on, so a reload sees a new version even when
/// the size stays the same and the clock's tick is coarse.
void rewrite(const std::filesystem::path& p, const std::string& text) {
  static int bump = 0;
  const auto before = std::filesystem::last_write_time(p);
  test::writeText(p, text);
  std::filesystem::last_write_time(p, before + std::chrono::seconds(2 + bump++));
}

// ---- the server process ----------------------------------------------------------------------

void writeLine(int fd, const std::string& line) {
  const std::string text = line + "\n";
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n <= 0) return;
    done += size_t(n);
  }
}

std::string countersLine(const ZapCounters& c) {
  return "COUNTERS " + std::to_string(c.allowed) + " " + std::to_string(c.refused_unknown_key) +
         " " + std::to_string(c.refused_mechanism) + " " + std::to_string(c.malformed) + " " +
         std::to_string(c.refused_domain);
}

/// The child: a CURVE ROUTER echoing "echo:<payload>", telling the parent on `events` its port,
/// each message it takes (with its User-Id) and the ZAP handler's counters. Ends when the parent
/// closes `commands` (or after a minute at the most).
[[noreturn]] void serve(int events, int commands, const KeyPair& keys,
                        const std::filesystem::path& allow, const std::filesystem::path& log) {
  const int log_fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0600);
  if (log_fd >= 0) ::dup2(log_fd, 2);
  int rc = 0;
  try {
    zmq::context_t context(1);
    auto list = std::make_shared<AllowList>(allow);
    ZapHandler zap(context, list);
    zmq::socket_t router(context, zmq::socket_type::router);
    router.set(zmq::sockopt::linger, 0);
    curveServer(router, keys);
    router.bind("tcp://127.0.0.1:0");
    const std::string endpoint = router.get(zmq::sockopt::last_endpoint);
    writeLine(events, "PORT " + endpoint.substr(endpoint.rfind(':') + 1));
    ZapCounters told{};
    writeLine(events, countersLine(told));
    const auto deadline = Clock::now() + 60s;
    while (Clock::now() < deadline) {
      zmq::pollitem_t items[] = {{router.handle(), 0, ZMQ_POLLIN, 0},
                                 {nullptr, commands, ZMQ_POLLIN, 0}};
      zmq::poll(items, 2, 20ms);
      if (items[1].revents) {
        char c;
        if (::read(commands, &c, 1) <= 0) break;
      }
      std::vector<zmq::message_t> parts;
      if ((items[0].revents & ZMQ_POLLIN) &&
          zmq::recv_multipart(router, std::back_inserter(parts), zmq::recv_flags::dontwait) &&
          parts.size() >= 2) {
        const char* user = zmq_msg_gets(parts[1].handle(), "User-Id");
        writeLine(events, "MSG " + std::string(user ? user : "-") + " " + parts[1].to_string());
        const std::string reply = "echo:" + parts[1].to_string();
        std::array<zmq::const_buffer, 2> out = {zmq::buffer(parts[0].data(), parts[0].size()),
                                                zmq::buffer(reply)};
        zmq::send_multipart(router, out, zmq::send_flags::dontwait);
      }
      const ZapCounters now = zap.counters();
      if (countersLine(now) != countersLine(told)) {
        told = now;
        writeLine(events, countersLine(told));
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "test server: %s\n", e.what());
    writeLine(events, std::string("ERROR ") + e.what());
    rc = 1;
  }
  std::fflush(stderr);
  ::_exit(rc);
}

/// The forked server as the parent sees it. Create it before any ZMQ context of the test.
class ServerProcess {
 public:
  struct Message {
    std::string user_id, payload;
  };

  ServerProcess(const KeyPair& keys, const std::filesystem::path& allow,
                const std::filesystem::path& log)
      : mLog(log) {
    int events[2], commands[2];
    if (::pipe2(events, O_CLOEXEC) != 0 || ::pipe2(commands, O_CLOEXEC) != 0)
      throw std::runtime_error("pipe2 failed");
    mPid = ::fork();
    if (mPid == 0) {
      ::close(events[0]);
      ::close(commands[1]);
      serve(events[1], commands[0], keys, allow, log);
    }
    ::close(events[1]);
    ::close(commands[0]);
    mEvents = events[0];
    mCommands = commands[1];
    waitFor([&] { return mPort != 0 || !mError.empty(); }, 20s);
    if (mPort == 0) {
      stop();
      throw std::runtime_error("the test server did not start: " + mError);
    }
  }
  ~ServerProcess() { stop(); }
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  /// Ends the child (closing its command pipe; SIGKILL if it is still there after 10 s).
  void stop() {
    if (mPid <= 0) return;
    ::close(mCommands);  // the child's signal to end
    const auto deadline = Clock::now() + 10s;
    int status = 0;
    while (::waitpid(mPid, &status, WNOHANG) == 0) {
      if (Clock::now() > deadline) {
        ::kill(mPid, SIGKILL);
        ::waitpid(mPid, &status, 0);
        break;
      }
      std::this_thread::sleep_for(10ms);
    }
    ::close(mEvents);
    mPid = -1;
  }

  int port() const { return mPort; }
  std::string endpoint() const { return "tcp://127.0.0.1:" + std::to_string(mPort); }
  std::string log() const { return readText(mLog); }

  /// Reads the child's events for `time`.
  void pump(std::chrono::milliseconds time) {
    pollfd p{mEvents, POLLIN, 0};
    if (::poll(&p, 1, int(time.count())) <= 0) return;
    char buffer[4096];
    const ssize_t n = ::read(mEvents, buffer, sizeof buffer);
    if (n <= 0) return;
    mPending.append(buffer, size_t(n));
    for (size_t end = mPending.find('\n'); end != std::string::npos; end = mPending.find('\n')) {
      take(mPending.substr(0, end));
      mPending.erase(0, end + 1);
    }
  }

  /// Pumps until `done()` or `timeout`; returns done().
  bool waitFor(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (!done() && Clock::now() < deadline) pump(20ms);
    return done();
  }

  const std::vector<Message>& messages() const { return mMessages; }
  const ZapCounters& counters() const { return mCounters; }

 private:
  void take(const std::string& line) {
    if (line.rfind("PORT ", 0) == 0) {
      mPort = std::stoi(line.substr(5));
    } else if (line.rfind("MSG ", 0) == 0) {
      const size_t space = line.find(' ', 4);
      mMessages.push_back({line.substr(4, space - 4), line.substr(space + 1)});
    } else if (line.rfind("COUNTERS ", 0) == 0) {
      std::istringstream in(line.substr(9));
      in >> mCounters.allowed >> mCounters.refused_unknown_key >> mCounters.refused_mechanism >>
          mCounters.malformed >> mCounters.refused_domain;
    } else if (line.rfind("ERROR ", 0) == 0) {
      mError = line.substr(6);
    }
  }

  std::filesystem::path mLog;
  pid_t mPid = -1;
  int mEvents = -1, mCommands = -1, mPort = 0;
  std::string mPending, mError;
  std::vector<Message> mMessages;
  ZapCounters mCounters;
};

// ---- clients ---------------------------------------------------------------------------------

/// A DEALER configured by `setup`, connected to `endpoint`, sending `payload`: the reply, or
/// std::nullopt when none came within `wait`.
std::optional<std::string> ask(const std::string& endpoint,
                               const std::function<void(zmq::socket_t&)>& setup,
                               const std::string& payload, std::chrono::milliseconds wait) {
  zmq::context_t context(1);
  zmq::socket_t dealer(context, zmq::socket_type::dealer);
  dealer.set(zmq::sockopt::linger, 0);
  setup(dealer);
  dealer.connect(endpoint);
  dealer.send(zmq::buffer(payload), zmq::send_flags::dontwait);
  zmq::pollitem_t item{dealer.handle(), 0, ZMQ_POLLIN, 0};
  if (zmq::poll(&item, 1, wait) == 0) return std::nullopt;
  zmq::message_t reply;
  if (!dealer.recv(reply, zmq::recv_flags::dontwait)) return std::nullopt;
  return reply.to_string();
}

std::function<void(zmq::socket_t&)> asCurveClient(const KeyPair& keys,
                                                  const std::string& server_key) {
  return [=](zmq::socket_t& s) { curveClient(s, keys, server_key); };
}

/// A test's keys and files: the server's pair, an allowed site and an unknown one.
struct Fixture {
  TempDir dir;
  KeyPair server = generateKeyPair(), site = generateKeyPair(), stranger = generateKeyPair();
  std::filesystem::path allow = dir / "allow.txt", log = dir / "server.log";

  Fixture() { writeAllowList(allow, "# sites\n" + site.public_key + " venice\n"); }
};

// ---- the handshake ---------------------------------------------------------------------------

TEST(CurveLink, AllowedKeyGetsTheReplyWithItsKeyAsUserId) {
  Fixture f;
  ServerProcess server(f.server, f.allow, f.log);
  EXPECT_EQ(
      ask(server.endpoint(), asCurveClient(f.site, f.server.public_key), "hello", kReplyWithin),
      "echo:hello");
  ASSERT_TRUE(server.waitFor([&] { return !server.messages().empty(); }, 5s));
  EXPECT_EQ(server.messages()[0].user_id, f.site.public_key);
  EXPECT_EQ(server.messages()[0].payload, "hello");
  EXPECT_TRUE(server.waitFor([&] { return server.counters().allowed >= 1; }, 5s));
}

TEST(CurveLink, UnknownKeyGetsNothingAndIsCountedAndLoggedRateLimited) {
  Fixture f;
  const auto started = Clock::now();
  ServerProcess server(f.server, f.allow, f.log);
  EXPECT_EQ(ask(server.endpoint(), asCurveClient(f.stranger, f.server.public_key), "let-me-in",
                kNothingWithin),
            std::nullopt);
  EXPECT_TRUE(server.waitFor([&] { return server.counters().refused_unknown_key >= 1; }, 5s));
  server.pump(200ms);
  EXPECT_TRUE(server.messages().empty());
  EXPECT_EQ(server.counters().allowed, 0u);

  // Who and why, with the key's first 8 characters, never the whole key.
  std::string log = server.log();
  EXPECT_NE(log.find("refused 127.0.0.1: key " + f.stranger.public_key.substr(0, 8)),
            std::string::npos)
      << log;
  EXPECT_EQ(log.find(f.stranger.public_key), std::string::npos) << "the whole key is logged";

  // A refused libzmq client does not try again by itself, so a burst of strangers: at most a
  // line a second for the reason, however many were refused.
  constexpr int kBurst = 8;
  {
    zmq::context_t context(1);
    std::vector<zmq::socket_t> dealers;
    for (int i = 0; i < kBurst; ++i) {
      dealers.emplace_back(context, zmq::socket_type::dealer);
      dealers.back().set(zmq::sockopt::linger, 0);
      curveClient(dealers.back(), generateKeyPair(), f.server.public_key);
      dealers.back().connect(server.endpoint());
      dealers.back().send(zmq::str_buffer("let-me-in"), zmq::send_flags::dontwait);
    }
    EXPECT_TRUE(
        server.waitFor([&] { return server.counters().refused_unknown_key >= 1 + kBurst; }, 10s));
  }
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(Clock::now() - started);
  server.pump(100ms);
  log = server.log();
  const size_t lines = countOf(log, "is not on");
  EXPECT_GE(lines, 1u);
  EXPECT_LE(lines, size_t(seconds.count()) + 1) << log;
  EXPECT_TRUE(server.messages().empty());
}

TEST(CurveLink, PlaintextClientGetsNothing) {
  Fixture f;
  ServerProcess server(f.server, f.allow, f.log);
  EXPECT_EQ(ask(
                server.endpoint(), [](zmq::socket_t&) {}, "plain", kNothingWithin),
            std::nullopt);
  // Also a NULL client that names the ZAP domain: the server is CURVE, so the mechanisms do not
  // match at the greeting and no ZAP request is ever made.
  EXPECT_EQ(
      ask(
          server.endpoint(), [](zmq::socket_t& s) { s.set(zmq::sockopt::zap_domain, "tessera"); },
          "plain", kNothingWithin),
      std::nullopt);
  server.pump(200ms);
  EXPECT_TRUE(server.messages().empty());
  EXPECT_EQ(server.counters().allowed, 0u);
  EXPECT_EQ(server.counters().refused_mechanism, 0u) << "a NULL peer reached the ZAP handler";
}

TEST(CurveLink, ClientTrustingAnotherServerKeyGetsNothing) {
  Fixture f;
  ServerProcess server(f.server, f.allow, f.log);
  const KeyPair impostor = generateKeyPair();
  // The site's own key is on the list, but it encrypts its HELLO for another server: ours
  // cannot open it, so the handshake ends before the ZAP handler is asked.
  EXPECT_EQ(
      ask(server.endpoint(), asCurveClient(f.site, impostor.public_key), "hello", kNothingWithin),
      std::nullopt);
  server.pump(200ms);
  EXPECT_TRUE(server.messages().empty());
  EXPECT_EQ(server.counters().allowed, 0u);
  EXPECT_EQ(server.counters().refused_unknown_key, 0u);
}

// ---- replay ----------------------------------------------------------------------------------

int listenOnLoopback(int& port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof addr;
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::listen(fd, 4) != 0 || ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0)
    throw std::runtime_error(std::string("listen on 127.0.0.1: ") + std::strerror(errno));
  port = ntohs(addr.sin_port);
  return fd;
}

int connectToLoopback(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = htons(uint16_t(port));
  if (fd < 0 || ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
    throw std::runtime_error(std::string("connect to 127.0.0.1: ") + std::strerror(errno));
  return fd;
}

/// A TCP proxy on 127.0.0.1 for one connection to `target_port`, recording what the client
/// sends. Plain POSIX sockets and poll(), on its own thread.
class RecordingProxy {
 public:
  explicit RecordingProxy(int target_port) : mTarget(target_port) {
    mListen = listenOnLoopback(mPort);
    mThread = std::thread([this] { run(); });
  }
  ~RecordingProxy() {
    mStop = true;
    mThread.join();
    ::close(mListen);
  }

  int port() const { return mPort; }
  /// Waits (at most `timeout`) for the proxied connection to end; the client's bytes.
  std::string clientBytes(std::chrono::milliseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (!mDone && Clock::now() < deadline) std::this_thread::sleep_for(10ms);
    std::lock_guard lock(mMutex);
    return mClientBytes;
  }

 private:
  void run() {
    pollfd l{mListen, POLLIN, 0};
    const auto deadline = Clock::now() + 30s;
    while (!mStop && Clock::now() < deadline && ::poll(&l, 1, 20) == 0) {
    }
    if (mStop || !(l.revents & POLLIN)) return;
    const int client = ::accept4(mListen, nullptr, nullptr, SOCK_CLOEXEC);
    const int server = connectToLoopback(mTarget);
    pollfd p[2] = {{client, POLLIN, 0}, {server, POLLIN, 0}};
    char buffer[16384];
    while (!mStop && Clock::now() < deadline) {
      if (::poll(p, 2, 20) <= 0) continue;
      bool closed = false;
      for (int i = 0; i < 2; ++i) {
        if (!(p[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
        const ssize_t n = ::read(p[i].fd, buffer, sizeof buffer);
        if (n <= 0) {
          closed = true;
          break;
        }
        if (i == 0) {
          std::lock_guard lock(mMutex);
          mClientBytes.append(buffer, size_t(n));
        }
        ::send(p[1 - i].fd, buffer, size_t(n), MSG_NOSIGNAL);
      }
      if (closed) break;
    }
    ::close(client);
    ::close(server);
    mDone = true;
  }

  int mTarget, mListen = -1, mPort = 0;
  std::atomic<bool> mStop{false}, mDone{false};
  std::mutex mMutex;
  std::string mClientBytes;
  std::thread mThread;
};

TEST(CurveLink, ReplayedSessionDeliversNothing) {
  Fixture f;
  ServerProcess server(f.server, f.allow, f.log);
  RecordingProxy proxy(server.port());
  const std::string proxied = "tcp://127.0.0.1:" + std::to_string(proxy.port());
  ASSERT_EQ(ask(proxied, asCurveClient(f.site, f.server.public_key), "transfer-42", kReplyWithin),
            "echo:transfer-42");
  const std::string recorded = proxy.clientBytes(5s);
  ASSERT_TRUE(server.waitFor([&] { return server.messages().size() == 1; }, 5s));
  ASSERT_TRUE(server.waitFor([&] { return server.counters().allowed == 1; }, 5s));

  // What was recorded is a whole CURVE session (greeting, HELLO, INITIATE, MESSAGE), and none
  // of it is the plaintext.
  EXPECT_EQ(uint8_t(recorded.at(0)), 0xFF);
  EXPECT_NE(recorded.find("CURVE"), std::string::npos);
  EXPECT_NE(recorded.find("\x05HELLO"), std::string::npos);
  EXPECT_NE(recorded.find("\x08INITIATE"), std::string::npos);
  EXPECT_NE(recorded.find("\x07MESSAGE"), std::string::npos);
  EXPECT_EQ(recorded.find("transfer-42"), std::string::npos) << "the message went in the clear";

  // The same bytes again on a fresh connection: the server's WELCOME carries a new short-term
  // key and cookie, so the old INITIATE does not open and the connection ends in the handshake.
  const int raw = connectToLoopback(server.port());
  ::send(raw, recorded.data(), recorded.size(), MSG_NOSIGNAL);
  std::string answer;
  bool closed = false;
  const auto deadline = Clock::now() + kNothingWithin;
  while (!closed && Clock::now() < deadline) {
    pollfd p{raw, POLLIN, 0};
    if (::poll(&p, 1, 20) <= 0) continue;
    char buffer[4096];
    const ssize_t n = ::read(raw, buffer, sizeof buffer);
    if (n <= 0)
      closed = true;
    else
      answer.append(buffer, size_t(n));
  }
  ::close(raw);
  server.pump(300ms);
  EXPECT_EQ(server.messages().size(), 1u) << "the replayed message reached the application";
  EXPECT_EQ(server.counters().allowed, 1u) << "the replayed handshake was admitted";
  EXPECT_EQ(answer.find("\x05READY"), std::string::npos) << "the server finished the handshake";
  EXPECT_TRUE(closed) << "the server kept a replaying connection open";
}

// ---- the allow list, live --------------------------------------------------------------------

TEST(CurveLink, AllowListChangesApplyToTheNextConnection) {
  Fixture f;
  ServerProcess server(f.server, f.allow, f.log);
  const auto stranger = asCurveClient(f.stranger, f.server.public_key);
  const auto site = asCurveClient(f.site, f.server.public_key);
  EXPECT_EQ(ask(server.endpoint(), stranger, "a", kNothingWithin), std::nullopt);

  // Added: admitted without a restart.
  rewrite(f.allow, f.site.public_key + " venice\n" + f.stranger.public_key + " lyon\n");
  EXPECT_EQ(ask(server.endpoint(), stranger, "b", kReplyWithin), "echo:b");

  // Removed: refused on the next connection.
  rewrite(f.allow, f.stranger.public_key + " lyon\n");
  const uint64_t refused = (server.pump(100ms), server.counters().refused_unknown_key);
  EXPECT_EQ(ask(server.endpoint(), site, "c", kNothingWithin), std::nullopt);
  EXPECT_TRUE(server.waitFor([&] { return server.counters().refused_unknown_key > refused; }, 5s));

  // Malformed: the previous list stays (lyon still gets in) and the line is named, once.
  rewrite(f.allow, f.stranger.public_key + " lyon\nnot-a-key paris\n");
  EXPECT_EQ(ask(server.endpoint(), stranger, "d", kReplyWithin), "echo:d");
  EXPECT_EQ(ask(server.endpoint(), stranger, "e", kReplyWithin), "echo:e");
  EXPECT_EQ(ask(server.endpoint(), site, "f", kNothingWithin), std::nullopt);
  ASSERT_TRUE(server.waitFor([&] { return server.messages().size() == 3; }, 5s));
  for (const auto& m : server.messages()) EXPECT_EQ(m.user_id, f.stranger.public_key);
  const std::string log = server.log();
  EXPECT_EQ(countOf(log, f.allow.string() + ":2: 'not-a-key' is not a Z85 public key"), 1u) << log;
  EXPECT_NE(log.find("keeping the previous list (1 key)"), std::string::npos) << log;
}

// ---- the ZAP handler's other answers (one process, real TCP) ---------------------------------

/// A server socket of `type` in `context` set up by `setup` on 127.0.0.1; its endpoint.
std::string bindLoopback(zmq::socket_t& socket, const std::function<void(zmq::socket_t&)>& setup) {
  socket.set(zmq::sockopt::linger, 0);
  setup(socket);
  socket.bind("tcp://127.0.0.1:0");
  return socket.get(zmq::sockopt::last_endpoint);
}

/// Waits up to `timeout` for `done()` (a counter the ZAP thread moves).
bool eventually(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  while (!done() && Clock::now() < deadline) std::this_thread::sleep_for(10ms);
  return done();
}

/// Answers "ok" to every message of a ROUTER on its own thread (which then owns the socket).
class Echo {
 public:
  explicit Echo(zmq::socket_t& router) : mThread([this, &router] { run(router); }) {}
  ~Echo() {
    mStop = true;
    mThread.join();
  }
  int received() const { return mReceived.load(); }

 private:
  void run(zmq::socket_t& router) {
    router.set(zmq::sockopt::rcvtimeo, 20);
    while (!mStop) {
      std::vector<zmq::message_t> parts;
      if (zmq::recv_multipart(router, std::back_inserter(parts)) && parts.size() == 2) {
        ++mReceived;
        std::array<zmq::const_buffer, 2> out = {zmq::buffer(parts[0].data(), parts[0].size()),
                                                zmq::str_buffer("ok")};
        zmq::send_multipart(router, out);
      }
    }
  }

  std::atomic<bool> mStop{false};
  std::atomic<int> mReceived{0};
  std::thread mThread;
};

TEST(ZapHandler, RefusesNullAndPlainMechanismsAndOtherDomains) {
  Fixture f;
  zmq::context_t context(1);
  ZapHandler zap(context, std::make_shared<AllowList>(f.allow));

  // A NULL server socket that asks ZAP (domain set): its NULL clients are refused.
  zmq::socket_t null_server(context, zmq::socket_type::router);
  const std::string null_endpoint = bindLoopback(
      null_server, [](zmq::socket_t& s) { s.set(zmq::sockopt::zap_domain, "tessera"); });
  EXPECT_EQ(ask(
                null_endpoint, [](zmq::socket_t&) {}, "x", kNothingWithin),
            std::nullopt);
  EXPECT_TRUE(eventually([&] { return zap.counters().refused_mechanism >= 1; }, 5s));

  // PLAIN, whatever the password.
  zmq::socket_t plain_server(context, zmq::socket_type::router);
  const std::string plain_endpoint = bindLoopback(plain_server, [](zmq::socket_t& s) {
    s.set(zmq::sockopt::plain_server, true);
    s.set(zmq::sockopt::zap_domain, "tessera");
  });
  const uint64_t before = zap.counters().refused_mechanism;
  EXPECT_EQ(ask(
                plain_endpoint,
                [](zmq::socket_t& s) {
                  s.set(zmq::sockopt::plain_username, "admin");
                  s.set(zmq::sockopt::plain_password, "admin");
                },
                "x", kNothingWithin),
            std::nullopt);
  EXPECT_TRUE(eventually([&] { return zap.counters().refused_mechanism > before; }, 5s));

  // A CURVE socket of another domain on the same context: an allowed key is still refused.
  zmq::socket_t other(context, zmq::socket_type::router);
  const std::string other_endpoint = bindLoopback(other, [&](zmq::socket_t& s) {
    curveServer(s, f.server);
    s.set(zmq::sockopt::zap_domain, "elsewhere");
  });
  EXPECT_EQ(ask(other_endpoint, asCurveClient(f.site, f.server.public_key), "x", kNothingWithin),
            std::nullopt);
  EXPECT_TRUE(eventually([&] { return zap.counters().refused_domain >= 1; }, 5s));
  EXPECT_EQ(zap.counters().allowed, 0u);

  // And the same context's proper server admits the site: the refusals above were the rules.
  zmq::socket_t proper(context, zmq::socket_type::router);
  const std::string proper_endpoint =
      bindLoopback(proper, [&](zmq::socket_t& s) { curveServer(s, f.server); });
  {
    Echo echo(proper);
    EXPECT_EQ(ask(proper_endpoint, asCurveClient(f.site, f.server.public_key), "x", kReplyWithin),
              "ok");
  }
  EXPECT_EQ(zap.counters().allowed, 1u);
}

TEST(ZapHandler, OnePerContext) {
  Fixture f;
  zmq::context_t context(1);
  auto list = std::make_shared<AllowList>(f.allow);
  ZapHandler first(context, list);
  try {
    ZapHandler second(context, list);
    FAIL() << "a second handler bound the same context";
  } catch (const KeyError& e) {
    EXPECT_NE(std::string(e.what()).find("inproc://zeromq.zap.01"), std::string::npos) << e.what();
  }
}

TEST(ZapHandler, WithoutAHandlerTheServerRefusesEveryone) {
  // curveServer() sets ZMQ_ZAP_ENFORCE_DOMAIN: a context without a ZAP handler admits nobody.
  // Without the option libzmq would admit any CURVE client (the control below), which is why
  // it is set.
  Fixture f;
  for (const bool enforce : {true, false}) {
    SCOPED_TRACE(enforce ? "enforced" : "not enforced (libzmq's default)");
    zmq::context_t context(1);
    zmq::socket_t router(context, zmq::socket_type::router);
    const std::string endpoint = bindLoopback(router, [&](zmq::socket_t& s) {
      curveServer(s, f.server);
      if (!enforce) {
        const int off = 0;
        ASSERT_EQ(zmq_setsockopt(s.handle(), 93 /* ZMQ_ZAP_ENFORCE_DOMAIN */, &off, sizeof off), 0);
      }
    });
    Echo echo(router);
    const auto reply = ask(endpoint, asCurveClient(f.stranger, f.server.public_key), "x",
                           enforce ? std::chrono::milliseconds(kNothingWithin) : kReplyWithin);
    if (enforce) {
      EXPECT_EQ(reply, std::nullopt);
      EXPECT_EQ(echo.received(), 0);
    } else {
      EXPECT_EQ(reply, "ok");
    }
  }
}

// ---- key files -------------------------------------------------------------------------------

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const KeyError& e) {
    return e.what();
  }
  return "(no KeyError)";
}

TEST(KeyFile, WriteThenReadRoundTripsWithMode0600) {
  TempDir dir;
  const KeyPair keys = generateKeyPair();
  EXPECT_TRUE(isZ85Key(keys.public_key));
  EXPECT_TRUE(isZ85Key(keys.secret_key));
  writeKeyFile(dir / "site.key", keys);
  struct stat info {};
  ASSERT_EQ(::stat((dir / "site.key").c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0600u);
  const KeyPair back = readKeyFile(dir / "site.key");
  EXPECT_EQ(back.public_key, keys.public_key);
  EXPECT_EQ(back.secret_key, keys.secret_key);
  // No temporary file left beside it.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()),
                          std::filesystem::directory_iterator()),
            1);
}

TEST(KeyFile, ReadableByOthersIsRefusedWithTheFix) {
  TempDir dir;
  const std::filesystem::path p = dir / "site.key";
  writeKeyFile(p, generateKeyPair());
  ::chmod(p.c_str(), 0644);
  EXPECT_EQ(errorOf([&] { readKeyFile(p); }), "collab::readKeyFile(): " + p.string() +
                                                  ": readable by others (mode 0644): chmod 600 " +
                                                  p.string());
  ::chmod(p.c_str(), 0620);
  EXPECT_NE(errorOf([&] { readKeyFile(p); }).find("writable by others (mode 0620)"),
            std::string::npos);
}

TEST(KeyFile, AnExistingFileIsNeverOverwritten) {
  TempDir dir;
  const std::filesystem::path p = dir / "site.key";
  const KeyPair first = generateKeyPair();
  writeKeyFile(p, first);
  EXPECT_NE(errorOf([&] { writeKeyFile(p, generateKeyPair()); }).find("already exists"),
            std::string::npos);
  EXPECT_EQ(readKeyFile(p).secret_key, first.secret_key);
  // Nor is a symlink's target.
  std::filesystem::create_symlink(dir / "elsewhere", dir / "link.key");
  EXPECT_NE(errorOf([&] { writeKeyFile(dir / "link.key", first); }).find("already exists"),
            std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir / "elsewhere"));
}

/// A key file with `text`, mode 0600.
std::filesystem::path keyFile(const TempDir& dir, const std::string& text) {
  const std::filesystem::path p = dir / "hand.key";
  std::filesystem::remove(p);
  test::writeText(p, text);
  ::chmod(p.c_str(), 0600);
  return p;
}

TEST(KeyFile, MalformedKeysAreRefusedNamingTheLine) {
  TempDir dir;
  const KeyPair keys = generateKeyPair();
  const std::string pub = "public = \"" + keys.public_key + "\"\n";
  const std::string sec = "secret = \"" + keys.secret_key + "\"\n";
  EXPECT_EQ(readKeyFile(keyFile(dir, "# mine\n\n" + pub + sec)).public_key, keys.public_key);

  std::string e = errorOf([&] {
    readKeyFile(keyFile(dir, pub + "secret = \"" + keys.secret_key.substr(0, 39) + "\"\n"));
  });
  EXPECT_NE(e.find("hand.key:2: the secret key is not a Z85 key"), std::string::npos) << e;
  EXPECT_EQ(e.find(keys.secret_key.substr(0, 39)), std::string::npos) << "the secret is quoted";
  // A character outside the Z85 alphabet.
  std::string bad = keys.public_key;
  bad[7] = ',';
  e = errorOf([&] { readKeyFile(keyFile(dir, "public = \"" + bad + "\"\n" + sec)); });
  EXPECT_NE(e.find("hand.key:1: the public key is not a Z85 key"), std::string::npos) << e;
  e = errorOf([&] { readKeyFile(keyFile(dir, pub + "secret " + keys.secret_key + "\n")); });
  EXPECT_NE(e.find("hand.key:2: expected public = "), std::string::npos) << e;
  e = errorOf([&] { readKeyFile(keyFile(dir, pub)); });
  EXPECT_NE(e.find("no secret"), std::string::npos) << e;
  e = errorOf([&] { readKeyFile(keyFile(dir, pub + pub + sec)); });
  EXPECT_NE(e.find("hand.key:2: a second public key"), std::string::npos) << e;
  e = errorOf([&] { readKeyFile(dir / "missing.key"); });
  EXPECT_NE(e.find("missing.key: cannot open"), std::string::npos) << e;
  // A FIFO is refused, not waited on.
  ASSERT_EQ(::mkfifo((dir / "fifo.key").c_str(), 0600), 0);
  e = errorOf([&] { readKeyFile(dir / "fifo.key"); });
  EXPECT_NE(e.find("fifo.key: not a regular file (a FIFO)"), std::string::npos) << e;
}

TEST(KeyFile, PublicKeyMustBelongToTheSecretKey) {
  TempDir dir;
  const KeyPair a = generateKeyPair(), b = generateKeyPair();
  const std::string e = errorOf([&] {
    readKeyFile(
        keyFile(dir, "public = \"" + a.public_key + "\"\nsecret = \"" + b.secret_key + "\"\n"));
  });
  EXPECT_NE(e.find("the public key is not the one of the secret key"), std::string::npos) << e;
  // Nor is a mixed pair written, or given to a socket.
  EXPECT_NE(errorOf([&] {
              writeKeyFile(dir / "mixed.key", {a.public_key, b.secret_key});
            }).find("not a key pair"),
            std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir / "mixed.key"));
  zmq::context_t context(1);
  zmq::socket_t s(context, zmq::socket_type::router);
  EXPECT_NE(errorOf([&] {
              curveServer(s, {a.public_key, b.secret_key});
            }).find("curveServer"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { curveClient(s, a, "too-short"); }).find("server key"), std::string::npos);
}

TEST(KeyFile, ReadPublicKeyFromAStringOrAFile) {
  TempDir dir;
  const KeyPair keys = generateKeyPair();
  EXPECT_EQ(readPublicKey(keys.public_key, "--server-key"), keys.public_key);
  writeKeyFile(dir / "master.key", keys);
  EXPECT_EQ(readPublicKey((dir / "master.key").string(), "--server-key"), keys.public_key);
  test::writeText(dir / "master.pub", keys.public_key + "\n");
  EXPECT_EQ(readPublicKey((dir / "master.pub").string(), "--server-key"), keys.public_key);
  test::writeText(dir / "only.pub", "# the master\npublic = \"" + keys.public_key + "\"\n");
  EXPECT_EQ(readPublicKey((dir / "only.pub").string(), "--server-key"), keys.public_key);

  std::string e = errorOf([&] { readPublicKey(keys.public_key.substr(1), "--server-key"); });
  EXPECT_EQ(e.rfind("--server-key: '", 0), 0u) << e;
  EXPECT_NE(e.find("neither a Z85 public key (40 characters) nor a file"), std::string::npos) << e;
  test::writeText(dir / "junk.pub", "hello\n");
  e = errorOf([&] { readPublicKey((dir / "junk.pub").string(), "--server-key"); });
  EXPECT_NE(e.find("--server-key: " + (dir / "junk.pub").string() + ":1:"), std::string::npos) << e;
}

TEST(KeyFile, Z85KeysAreFortyCharactersThatDecode) {
  const KeyPair keys = generateKeyPair();
  EXPECT_TRUE(isZ85Key(keys.public_key));
  EXPECT_FALSE(isZ85Key(""));
  EXPECT_FALSE(isZ85Key(keys.public_key + "0"));
  EXPECT_FALSE(isZ85Key(keys.public_key.substr(0, 35)));
  EXPECT_FALSE(isZ85Key(std::string(40, ' ')));
  EXPECT_FALSE(isZ85Key(std::string(40, '~')));
  // Each group of 5 characters must stay below 2^32: "#####" is 85^5 - 1, above it.
  EXPECT_FALSE(isZ85Key(std::string(40, '#')));
}

// ---- the allow list --------------------------------------------------------------------------

TEST(AllowList, ReadsKeysNamesAndComments) {
  TempDir dir;
  const KeyPair a = generateKeyPair(), b = generateKeyPair(), c = generateKeyPair();
  // '#' is in the Z85 alphabet but cannot begin a key, so "#<key>" is a comment.
  EXPECT_FALSE(isZ85Key("#" + b.public_key.substr(1)));
  writeAllowList(dir / "allow.txt", "# sites\n\n  " + a.public_key + "   venice lab # v2\n" +
                                        b.public_key + "\n#" + c.public_key + " retired\n");
  AllowList list(dir / "allow.txt");
  EXPECT_EQ(list.size(), 2u);
  EXPECT_EQ(list.find(a.public_key), "venice lab");
  EXPECT_EQ(list.find(b.public_key), "");
  EXPECT_EQ(list.find(c.public_key), std::nullopt);
  EXPECT_EQ(list.reload(), std::nullopt);  // unchanged
  EXPECT_EQ(list.generation(), 0u);
}

TEST(AllowList, MalformedLineNamesFileAndLine) {
  TempDir dir;
  const std::filesystem::path p = dir / "allow.txt";
  writeAllowList(p, "# sites\n" + generateKeyPair().public_key + "\nrq:rM>}U?@Lns47 short\n");
  const std::string e = errorOf([&] { AllowList list(p); });
  EXPECT_EQ(e, "collab::AllowList: " + p.string() +
                   ":3: 'rq:rM>}U?@Lns47' is not a Z85 public key (40 characters of the Z85 "
                   "alphabet)");
  EXPECT_NE(errorOf([&] { AllowList list(dir / "none.txt"); }).find("none.txt: cannot open"),
            std::string::npos);
  writeAllowList(p, "");
  ::chmod(p.c_str(), 0666);
  EXPECT_NE(errorOf([&] { AllowList list(p); }).find("writable by others (mode 0666)"),
            std::string::npos);
}

/// An allow list holding key `a`; `b` is another site's key.
struct ListFile {
  TempDir dir;
  std::filesystem::path p = dir / "allow.txt";
  KeyPair a = generateKeyPair(), b = generateKeyPair();
  ListFile() { writeAllowList(p, a.public_key + "\n"); }
};

TEST(AllowList, ReloadTakesChangesAndKeepsTheOldListOnABadOne) {
  ListFile l;
  const auto& [dir, p, a, b] = l;
  AllowList list(p);
  rewrite(p, a.public_key + "\n" + b.public_key + " lyon\n");
  EXPECT_EQ(list.reload(), std::nullopt);
  EXPECT_EQ(list.generation(), 1u);
  EXPECT_EQ(list.find(b.public_key), "lyon");

  rewrite(p, a.public_key + "\nbroken\n");
  const std::optional<std::string> reason = list.reload();
  ASSERT_TRUE(reason);
  EXPECT_NE(reason->find(p.string() + ":2: 'broken'"), std::string::npos) << *reason;
  EXPECT_NE(reason->find("keeping the previous list (2 keys)"), std::string::npos) << *reason;
  EXPECT_EQ(list.reload(), std::nullopt) << "the same bad version reported twice";
  EXPECT_EQ(list.generation(), 1u);
  EXPECT_EQ(list.find(b.public_key), "lyon");

  std::filesystem::remove(p);
  EXPECT_TRUE(list.reload());
  EXPECT_EQ(list.size(), 2u);
  writeAllowList(p, b.public_key + "\n");
  EXPECT_EQ(list.reload(), std::nullopt);
  EXPECT_EQ(list.size(), 1u);
  EXPECT_EQ(list.find(a.public_key), std::nullopt);
  EXPECT_EQ(list.generation(), 2u);
}

TEST(AllowList, FindAndReloadFromTwoThreads) {
  ListFile l;
  const auto& [dir, p, a, b] = l;
  AllowList list(p);
  std::atomic<bool> stop{false};
  std::thread reader([&] {
    while (!stop) {
      EXPECT_EQ(list.find(a.public_key), "");  // on every version written below
      list.reload();
    }
  });
  for (int i = 0; i < 50; ++i) {
    // Renamed into place, so the reader never sees a half-written list.
    writeAllowList(dir / "next.txt", a.public_key + "\n" + (i % 2 ? b.public_key + "\n" : ""));
    std::filesystem::rename(dir / "next.txt", p);
    list.reload();
  }
  stop = true;
  reader.join();
  EXPECT_GE(list.generation(), 1u);
}

}  // namespace
}  // namespace tessera::collab
