#include <tessera/collab/curve.h>
#include <tessera/sync/zmq_poll.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zmq.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <future>
#include <map>
#include <mutex>
#include <thread>

namespace tessera::collab {

namespace {

constexpr size_t kKeyChars = 40;
constexpr size_t kKeyBytes = 32;
constexpr const char* kZapDomain = "tessera";
constexpr const char* kZapEndpoint = "inproc://zeromq.zap.01";  // RFC 27's fixed address
constexpr off_t kMaxKeyFileBytes = 64 * 1024;
constexpr off_t kMaxAllowListBytes = 1024 * 1024;

// libzmq 4.3 keeps ZMQ_ZAP_ENFORCE_DOMAIN behind ZMQ_BUILD_DRAFT_API in zmq.h, but its
// setsockopt knows the option in every build (Debian's 4.3.4: zmq_has("draft") == 0 and the
// option is accepted). Without it a CURVE server whose context has no ZAP handler admits every
// client ("Stonehouse": encryption without authentication); with it, it refuses them.
#ifdef ZMQ_ZAP_ENFORCE_DOMAIN
constexpr int kZapEnforceDomain = ZMQ_ZAP_ENFORCE_DOMAIN;
#else
constexpr int kZapEnforceDomain = 93;  // zmq_draft.h of libzmq 4.3
#endif

std::string errnoText(int error) {
  return std::strerror(error);
}

std::string trim(const std::string& s) {
  const size_t first = s.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return "";
  const size_t last = s.find_last_not_of(" \t\r\n");
  return s.substr(first, last - first + 1);
}

std::string octalMode(mode_t mode) {
  char text[8];
  std::snprintf(text, sizeof text, "%04o", unsigned(mode & 07777));
  return text;
}

/// A file's bytes, read through one descriptor so the checks and the read see the same file.
/// O_NONBLOCK: a FIFO is refused by fstat() below instead of waiting for a writer.
struct OpenedFile {
  std::string bytes;
  struct stat info {};
};

OpenedFile readSmallFile(const std::filesystem::path& path, const char* who, off_t max_bytes) {
  const std::string name = path.string();
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    throw KeyError(std::string(who) + ": " + name + ": cannot open (" + errnoText(errno) + ")");
  }
  OpenedFile file;
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  if (::fstat(fd, &file.info) != 0) {
    throw KeyError(std::string(who) + ": " + name + ": cannot stat (" + errnoText(errno) + ")");
  }
  if (!S_ISREG(file.info.st_mode)) {
    const char* what = S_ISDIR(file.info.st_mode)    ? "a directory"
                       : S_ISFIFO(file.info.st_mode) ? "a FIFO"
                       : S_ISSOCK(file.info.st_mode) ? "a socket"
                                                     : "a device";
    throw KeyError(std::string(who) + ": " + name + ": not a regular file (" + what + ")");
  }
  if (file.info.st_size > max_bytes) {
    throw KeyError(std::string(who) + ": " + name + ": " + std::to_string(file.info.st_size) +
                   " bytes, more than a key file or allow list holds (at most " +
                   std::to_string(max_bytes) + ")");
  }
  file.bytes.resize(size_t(file.info.st_size));
  size_t got = 0;
  while (got < file.bytes.size()) {
    const ssize_t n = ::read(fd, file.bytes.data() + got, file.bytes.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      throw KeyError(std::string(who) + ": " + name + ": cannot read (" + errnoText(errno) + ")");
    }
    if (n == 0) break;  // shrank while we read it: parse what is there
    got += size_t(n);
  }
  file.bytes.resize(got);
  return file;
}

/// Splits text into lines (without '\n').
std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = text.find('\n', start);
    if (end == std::string::npos) {
      if (start < text.size()) out.push_back(text.substr(start));
      break;
    }
    out.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

/// The public key of `secret_key` (both Z85), or "" when the secret is not a key.
std::string publicOf(const std::string& secret_key) {
  char derived[kKeyChars + 1] = {};
  if (zmq_curve_public(derived, secret_key.c_str()) != 0) return "";
  return derived;
}

/// One `name = "value"` line of a key file: false when the line is not of that form.
bool parseAssignment(const std::string& line, std::string& name, std::string& value) {
  const size_t eq = line.find('=');
  if (eq == std::string::npos) return false;
  name = trim(line.substr(0, eq));
  const std::string rest = trim(line.substr(eq + 1));
  // Z85 has no '"', so the first '"' after the opening one closes the value.
  if (rest.size() < 2 || rest[0] != '"') return false;
  const size_t close = rest.find('"', 1);
  if (close == std::string::npos) return false;
  value = rest.substr(1, close - 1);
  const std::string tail = trim(rest.substr(close + 1));
  return tail.empty() || tail[0] == '#';
}

struct ParsedKeyFile {
  std::optional<std::string> public_key, secret_key;
};

/// The `public = ` and `secret = ` lines of a key file. KeyError naming `name`:line for a line
/// that is neither (never quoting a secret).
ParsedKeyFile parseKeyFile(const std::string& text, const std::string& name, const char* who) {
  ParsedKeyFile parsed;
  const std::vector<std::string> all = lines(text);
  for (size_t i = 0; i < all.size(); ++i) {
    const std::string line = trim(all[i]);
    if (line.empty() || line[0] == '#') continue;
    const std::string where = std::string(who) + ": " + name + ":" + std::to_string(i + 1) + ": ";
    std::string key, value;
    if (!parseAssignment(line, key, value)) {
      throw KeyError(where + "expected public = \"<40 Z85 characters>\" or secret = \"...\"");
    }
    std::optional<std::string>* slot = key == "public"   ? &parsed.public_key
                                       : key == "secret" ? &parsed.secret_key
                                                         : nullptr;
    if (!slot) throw KeyError(where + "unknown entry '" + key + "' (public or secret)");
    if (*slot) throw KeyError(where + "a second " + key + " key");
    if (!isZ85Key(value)) {
      throw KeyError(where + "the " + key + " key is not a Z85 key (" + std::to_string(kKeyChars) +
                     " characters of the Z85 alphabet; got " + std::to_string(value.size()) +
                     " characters)");
    }
    *slot = value;
  }
  return parsed;
}

}  // namespace

// ---- keys ------------------------------------------------------------------------------------

bool isZ85Key(const std::string& key) {
  static constexpr char kAlphabet[] =
      "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#";
  if (key.size() != kKeyChars) return false;
  if (key.find_first_not_of(kAlphabet) != std::string::npos) return false;
  // zmq_z85_decode also refuses 5-character groups above 2^32 - 1.
  uint8_t bytes[kKeyBytes];
  return zmq_z85_decode(bytes, key.c_str()) != nullptr;
}

KeyPair generateKeyPair() {
  char public_key[kKeyChars + 1] = {}, secret_key[kKeyChars + 1] = {};
  if (zmq_curve_keypair(public_key, secret_key) != 0) {
    throw KeyError("collab::generateKeyPair(): zmq_curve_keypair failed (" +
                   std::string(zmq_strerror(zmq_errno())) + "; libzmq without CURVE?)");
  }
  KeyPair keys{public_key, secret_key};
  explicit_bzero(secret_key, sizeof secret_key);
  return keys;
}

void writeKeyFile(const std::filesystem::path& path, const KeyPair& keys) {
  const char* who = "collab::writeKeyFile()";
  const std::string name = path.string();
  if (!isZ85Key(keys.public_key) || !isZ85Key(keys.secret_key) ||
      publicOf(keys.secret_key) != keys.public_key) {
    throw KeyError(std::string(who) + ": " + name +
                   ": not a key pair (two Z85 keys, the public one of the secret one)");
  }
  struct stat existing {};
  if (::lstat(path.c_str(), &existing) == 0) {
    throw KeyError(std::string(who) + ": " + name +
                   " already exists: a key is never overwritten (remove it first)");
  }

  // A temporary file beside the target (same file system, so the rename is atomic), created
  // 0600 from the start: the secret is never in a file anyone else could open.
  const std::filesystem::path folder = path.has_parent_path() ? path.parent_path() : ".";
  std::filesystem::path temp;
  int fd = -1;
  for (int attempt = 0; attempt < 100 && fd < 0; ++attempt) {
    temp = folder / ("." + path.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                     std::to_string(attempt));
    fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0600);
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0) {
    throw KeyError(std::string(who) + ": " + name + ": cannot create a temporary file in " +
                   folder.string() + " (" + errnoText(errno) + ")");
  }
  std::string text = "# tessera CURVE key pair: keep this file secret\npublic = \"" +
                     keys.public_key + "\"\nsecret = \"" + keys.secret_key + "\"\n";
  size_t written = 0;
  int error = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = n < 0 ? errno : EIO;
      break;
    }
    written += size_t(n);
  }
  explicit_bzero(text.data(), text.size());
  if (error == 0 && ::fsync(fd) != 0) error = errno;
  if (::close(fd) != 0 && error == 0) error = errno;
  if (error != 0) {
    ::unlink(temp.c_str());
    throw KeyError(std::string(who) + ": " + name + ": cannot write " + temp.string() + " (" +
                   errnoText(error) + ")");
  }
  // RENAME_NOREPLACE: a file that appeared since the lstat() above is not replaced either. File
  // systems without it get link() + unlink(), which refuses an existing target the same way.
  int rc = ::renameat2(AT_FDCWD, temp.c_str(), AT_FDCWD, path.c_str(), RENAME_NOREPLACE);
  if (rc != 0 && (errno == EINVAL || errno == ENOSYS)) {
    rc = ::link(temp.c_str(), path.c_str());
    if (rc == 0) ::unlink(temp.c_str());
  }
  if (rc != 0) {
    error = errno;
    ::unlink(temp.c_str());
    throw KeyError(std::string(who) + ": " + name +
                   (error == EEXIST ? std::string(" already exists: a key is never overwritten")
                                    : ": cannot rename " + temp.string() + " into place (" +
                                          errnoText(error) + ")"));
  }
  const int dir = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);  // the rename itself survives a crash
    ::close(dir);
  }
}

KeyPair readKeyFile(const std::filesystem::path& path) {
  const char* who = "collab::readKeyFile()";
  const std::string name = path.string();
  OpenedFile file = readSmallFile(path, who, kMaxKeyFileBytes);
  const mode_t mode = file.info.st_mode;
  if (mode & 077) {
    const char* what = (mode & 044)   ? "readable by others"
                       : (mode & 022) ? "writable by others"
                                      : "executable by others";
    explicit_bzero(file.bytes.data(), file.bytes.size());
    throw KeyError(std::string(who) + ": " + name + ": " + what + " (mode " + octalMode(mode) +
                   "): chmod 600 " + name);
  }
  ParsedKeyFile parsed;
  try {
    parsed = parseKeyFile(file.bytes, name, who);
  } catch (...) {
    explicit_bzero(file.bytes.data(), file.bytes.size());
    throw;
  }
  explicit_bzero(file.bytes.data(), file.bytes.size());
  if (!parsed.public_key) {
    throw KeyError(std::string(who) + ": " + name + ": no public = \"...\" line");
  }
  if (!parsed.secret_key) {
    throw KeyError(std::string(who) + ": " + name + ": no secret = \"...\" line (a public key " +
                   "alone is for readPublicKey(), not for a socket's own keys)");
  }
  if (publicOf(*parsed.secret_key) != *parsed.public_key) {
    throw KeyError(std::string(who) + ": " + name +
                   ": the public key is not the one of the secret key (the file mixes two pairs)");
  }
  return {*parsed.public_key, *parsed.secret_key};
}

std::string readPublicKey(const std::string& argument, const std::string& what) {
  if (isZ85Key(argument)) return argument;
  std::error_code ec;
  if (!std::filesystem::exists(argument, ec)) {
    throw KeyError(what + ": '" + argument + "' is neither a Z85 public key (" +
                   std::to_string(kKeyChars) + " characters) nor a file");
  }
  OpenedFile file = readSmallFile(argument, what.c_str(), kMaxKeyFileBytes);
  const std::string alone = trim(file.bytes);
  std::string key;
  if (isZ85Key(alone)) {
    key = alone;
  } else {
    const ParsedKeyFile parsed = parseKeyFile(file.bytes, argument, what.c_str());
    if (!parsed.public_key) {
      explicit_bzero(file.bytes.data(), file.bytes.size());
      throw KeyError(what + ": " + argument + ": no public = \"...\" line and not a key alone");
    }
    key = *parsed.public_key;
  }
  explicit_bzero(file.bytes.data(), file.bytes.size());
  return key;
}

// ---- allow list ------------------------------------------------------------------------------

namespace {

/// What identifies one version of a file without reading it.
struct FileStamp {
  bool exists = false;
  dev_t dev = 0;
  ino_t ino = 0;
  off_t size = 0;
  int64_t mtime_ns = 0;
  bool operator==(const FileStamp&) const = default;
};

FileStamp stampOf(const struct stat& info) {
  return {true, info.st_dev, info.st_ino, info.st_size,
          int64_t(info.st_mtim.tv_sec) * 1000000000 + info.st_mtim.tv_nsec};
}

using KeyNames = std::map<std::string, std::string>;

/// Reads and parses an allow list. KeyError naming the file and line.
KeyNames parseAllowList(const std::filesystem::path& path, FileStamp& stamp) {
  const char* who = "collab::AllowList";
  const std::string name = path.string();
  const OpenedFile file = readSmallFile(path, who, kMaxAllowListBytes);
  stamp = stampOf(file.info);
  // Public keys are not secret, but whoever can write the list can let anyone in.
  if (file.info.st_mode & 022) {
    throw KeyError(std::string(who) + ": " + name + ": writable by others (mode " +
                   octalMode(file.info.st_mode) + "): chmod go-w " + name);
  }
  KeyNames keys;
  const std::vector<std::string> all = lines(file.bytes);
  for (size_t i = 0; i < all.size(); ++i) {
    const std::string line = trim(all[i]);
    // '#' is a Z85 character, but never a key's first: a 5-character group beginning with it
    // (84 * 85^4) exceeds 2^32 - 1. So a line beginning with '#' is always a comment.
    if (line.empty() || line[0] == '#') continue;
    const size_t space = line.find_first_of(" \t");
    const std::string first = line.substr(0, space);
    if (!isZ85Key(first)) {
      throw KeyError(std::string(who) + ": " + name + ":" + std::to_string(i + 1) + ": '" +
                     first.substr(0, 48) + "' is not a Z85 public key (" +
                     std::to_string(kKeyChars) + " characters of the Z85 alphabet)");
    }
    std::string site = space == std::string::npos ? "" : trim(line.substr(space));
    if (!site.empty() && site[0] == '#') site.clear();
    const size_t comment = site.find(" #");
    if (comment != std::string::npos) site = trim(site.substr(0, comment));
    keys.emplace(first, site);  // a repeated key keeps its first name
  }
  return keys;
}

}  // namespace

struct AllowList::Impl {
  std::filesystem::path path;
  mutable std::mutex mutex;  // the ZAP thread's find() and reload() against the master's
  KeyNames keys;
  FileStamp stamp;  // of the last version read, good or bad
  uint64_t generation = 0;
};

AllowList::AllowList(std::filesystem::path path) : m(std::make_shared<Impl>()) {
  m->path = std::move(path);
  m->keys = parseAllowList(m->path, m->stamp);
}

std::optional<std::string> AllowList::reload() {
  std::lock_guard lock(m->mutex);
  struct stat info {};
  FileStamp now;
  int error = 0;
  if (::stat(m->path.c_str(), &info) == 0)
    now = stampOf(info);
  else
    error = errno;
  if (now == m->stamp) return std::nullopt;
  const std::string keeping = "; keeping the previous list (" + std::to_string(m->keys.size()) +
                              (m->keys.size() == 1 ? " key)" : " keys)");
  if (error != 0) {
    m->stamp = now;
    return "collab::AllowList: " + m->path.string() + ": cannot stat (" + errnoText(error) + ")" +
           keeping;
  }
  FileStamp read_stamp = now;
  try {
    KeyNames keys = parseAllowList(m->path, read_stamp);
    m->stamp = read_stamp;
    if (keys != m->keys) {
      m->keys = std::move(keys);
      ++m->generation;
    }
  } catch (const KeyError& e) {
    m->stamp = read_stamp;
    return e.what() + keeping;
  }
  return std::nullopt;
}

std::optional<std::string> AllowList::find(const std::string& public_key) const {
  std::lock_guard lock(m->mutex);
  const auto it = m->keys.find(public_key);
  if (it == m->keys.end()) return std::nullopt;
  return it->second;
}

size_t AllowList::size() const {
  std::lock_guard lock(m->mutex);
  return m->keys.size();
}

uint64_t AllowList::generation() const {
  std::lock_guard lock(m->mutex);
  return m->generation;
}

const std::filesystem::path& AllowList::path() const {
  return m->path;
}

// ---- ZAP handler -----------------------------------------------------------------------------

namespace {

/// At most one stderr line per second per reason; the lines left out are counted in the next.
class RateLimitedLog {
 public:
  void say(const std::string& reason, const std::string& line) {
    const auto now = std::chrono::steady_clock::now();
    Entry& e = mEntries[reason];
    if (e.printed && now - *e.printed < std::chrono::seconds(1)) {
      ++e.left_out;
      return;
    }
    std::string text = "collab::ZapHandler: " + line;
    if (e.left_out > 0) {
      text += " (and " + std::to_string(e.left_out) + " more like it in the last second)";
    }
    std::fprintf(stderr, "%s\n", text.c_str());
    e.printed = now;
    e.left_out = 0;
  }

 private:
  struct Entry {
    std::optional<std::chrono::steady_clock::time_point> printed;
    uint64_t left_out = 0;
  };
  std::map<std::string, Entry> mEntries;
};

/// A key's first characters for a log line: enough to find it in an allow list, not all of it.
std::string keyPrefix(const std::string& key) {
  return key.substr(0, 8) + "...";
}

}  // namespace

struct ZapHandler::Impl {
  zmq::context_t& context;
  std::shared_ptr<AllowList> allow;
  std::atomic<bool> stop{false};
  mutable std::mutex mutex;  // counters: the ZAP thread writes, counters() reads
  ZapCounters counters;
  RateLimitedLog log;  // ZAP thread only
  std::thread thread;

  Impl(zmq::context_t& c, std::shared_ptr<AllowList> a) : context(c), allow(std::move(a)) {}

  struct Reply {
    std::string status, text, user_id;
  };

  void count(uint64_t ZapCounters::*field) {
    std::lock_guard lock(mutex);
    counters.*field += 1;
  }

  /// RFC 27 request frames: version, request id, domain, address, identity, mechanism,
  /// credentials...
  Reply decide(const std::vector<zmq::message_t>& frames) {
    if (frames.size() < 6 || frames[0].to_string_view() != "1.0") {
      count(&ZapCounters::malformed);
      log.say(
          "malformed",
          "a malformed ZAP request (" + std::to_string(frames.size()) + " frames" +
              (frames.empty()
                   ? ""
                   : ", version '" + std::string(frames[0].to_string_view().substr(0, 8)) + "'") +
              ")");
      return {"500", "malformed ZAP request", ""};
    }
    const std::string domain = frames[2].to_string();
    const std::string address = frames[3].to_string();
    const std::string mechanism = frames[5].to_string();
    if (mechanism != "CURVE") {
      count(&ZapCounters::refused_mechanism);
      log.say("mechanism " + mechanism,
              "refused " + address + ": mechanism " + mechanism + " (site links are CURVE only)");
      return {"400", "CURVE only", ""};
    }
    if (domain != kZapDomain) {
      count(&ZapCounters::refused_domain);
      log.say("domain", "refused " + address + ": ZAP domain '" + domain + "' (expected '" +
                            kZapDomain + "')");
      return {"400", "unknown domain", ""};
    }
    if (frames.size() != 7 || frames[6].size() != kKeyBytes) {
      count(&ZapCounters::malformed);
      log.say("malformed", "a CURVE ZAP request from " + address + " without a 32-byte key");
      return {"500", "malformed ZAP request", ""};
    }
    char key[kKeyChars + 1] = {};
    zmq_z85_encode(key, static_cast<const uint8_t*>(frames[6].data()), kKeyBytes);
    if (const std::optional<std::string> problem = allow->reload()) {
      log.say("allow list", *problem);
    }
    if (!allow->find(key)) {
      count(&ZapCounters::refused_unknown_key);
      log.say("unknown key", "refused " + address + ": key " + keyPrefix(key) + " is not on " +
                                 allow->path().string());
      return {"400", "unknown key", ""};
    }
    count(&ZapCounters::allowed);
    return {"200", "OK", key};
  }

  void run(zmq::socket_t& socket) {
    while (!stop.load()) {
      try {
        zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
        // A short timeout: the destructor's stop flag is seen within it.
        if (sync::pollItems(&item, 1, std::chrono::milliseconds(100)) == 0) continue;
        std::vector<zmq::message_t> frames;
        if (!zmq::recv_multipart(socket, std::back_inserter(frames), zmq::recv_flags::dontwait))
          continue;
        const Reply reply = decide(frames);
        // A REP socket must answer before it can receive again, even a request it cannot read.
        const std::string request_id = frames.size() > 1 ? frames[1].to_string() : "";
        std::array<zmq::const_buffer, 6> parts = {
            zmq::str_buffer("1.0"),     zmq::buffer(request_id),
            zmq::buffer(reply.status),  zmq::buffer(reply.text),
            zmq::buffer(reply.user_id), zmq::const_buffer(nullptr, 0),  // metadata: none
        };
        zmq::send_multipart(socket, parts);
      } catch (const zmq::error_t& e) {
        if (e.num() == ETERM) return;
        log.say("zmq", std::string("ZAP socket error: ") + e.what());
      } catch (const std::exception& e) {
        // The handler must keep answering: a dead handler would leave handshakes waiting.
        log.say("internal", std::string("internal error: ") + e.what());
      }
    }
  }
};

ZapHandler::ZapHandler(zmq::context_t& context, std::shared_ptr<AllowList> allow)
    : m(std::make_unique<Impl>(context, std::move(allow))) {
  if (!m->allow) throw KeyError("collab::ZapHandler: no allow list");
  std::promise<void> bound;
  std::future<void> ready = bound.get_future();
  m->thread = std::thread([impl = m.get(), bound = std::move(bound)]() mutable {
    try {
      zmq::socket_t socket(impl->context, zmq::socket_type::rep);
      socket.set(zmq::sockopt::linger, 0);
      socket.bind(kZapEndpoint);
      bound.set_value();
      impl->run(socket);
    } catch (...) {
      try {
        bound.set_exception(std::current_exception());
      } catch (const std::future_error&) {
        // already bound: the exception came from the loop, which logs its own
      }
    }
  });
  try {
    ready.get();  // bound before the constructor returns, so server sockets never miss it
  } catch (const zmq::error_t& e) {
    m->thread.join();
    throw KeyError(std::string("collab::ZapHandler: cannot bind ") + kZapEndpoint + " (" +
                   e.what() + (e.num() == EADDRINUSE ? "; one ZAP handler per context" : "") + ")");
  } catch (...) {
    m->thread.join();  // a joinable std::thread must not be destroyed
    throw;
  }
}

ZapHandler::~ZapHandler() {
  m->stop.store(true);
  if (m->thread.joinable()) m->thread.join();
}

ZapCounters ZapHandler::counters() const {
  std::lock_guard lock(m->mutex);
  return m->counters;
}

// ---- sockets ---------------------------------------------------------------------------------

namespace {

void checkPair(const KeyPair& keys, const char* who) {
  if (!isZ85Key(keys.public_key) || !isZ85Key(keys.secret_key)) {
    throw KeyError(std::string(who) + ": the socket's keys are not Z85 keys (40 characters)");
  }
  if (publicOf(keys.secret_key) != keys.public_key) {
    throw KeyError(std::string(who) + ": the public key is not the one of the secret key");
  }
}

}  // namespace

void curveServer(zmq::socket_t& socket, const KeyPair& keys) {
  checkPair(keys, "collab::curveServer()");
  socket.set(zmq::sockopt::curve_server, true);
  socket.set(zmq::sockopt::curve_secretkey, keys.secret_key);
  socket.set(zmq::sockopt::curve_publickey, keys.public_key);
  socket.set(zmq::sockopt::zap_domain, kZapDomain);
  // Fail closed: a handshake with no ZAP handler on the context is refused, not admitted.
  // Older libzmq without the option (EINVAL) rely on the ZapHandler being there.
  const int on = 1;
  if (zmq_setsockopt(socket.handle(), kZapEnforceDomain, &on, sizeof on) != 0 &&
      zmq_errno() != EINVAL) {
    throw zmq::error_t();
  }
}

void curveClient(zmq::socket_t& socket, const KeyPair& keys, const std::string& server_public_key) {
  checkPair(keys, "collab::curveClient()");
  if (!isZ85Key(server_public_key)) {
    throw KeyError("collab::curveClient(): the server key is not a Z85 key (40 characters)");
  }
  socket.set(zmq::sockopt::curve_serverkey, server_public_key);
  socket.set(zmq::sockopt::curve_publickey, keys.public_key);
  socket.set(zmq::sockopt::curve_secretkey, keys.secret_key);
  socket.set(zmq::sockopt::zap_domain, kZapDomain);
}

}  // namespace tessera::collab
