// CURVE security for the site links (libzmq 4.3 with libsodium): key pairs and key
// files, the master's allow list of site public keys, and the ZAP handler that admits only
// those keys. A site link is a CURVE server socket on the master (curveServer()) and a CURVE
// client socket at each site (curveClient()); ZeroMQ encrypts and authenticates every message
// (CurveZMQ: Curve25519 key exchange, per-connection nonces, so a replayed handshake or message
// gets nothing). The master's ZAP handler (RFC 27) answers each handshake: a client key on the
// allow list passes with its key as the User-Id of every message it sends; an unknown key,
// a NULL (plaintext) or PLAIN client is refused before any message of the master reaches it.
//
// Key files are text, Z85 keys (40 characters), and must not be readable by anyone but their
// owner (mode 0600, as ssh does it):
//
//   # tessera CURVE key pair: keep this file secret
//   public = "rq:rM>}U?@Lns47E1%kR.o@n%FcmmsL/@{H8]yf7"
//   secret = "JTKVSB%%)wK0E.X)V>+}o?pNmC{O&4W4b!Ni{Lh6"
//
// The allow list is text, one site per line: its public key, then optionally its name; '#'
// starts a comment (a Z85 character, but never a key's first one: the group it began would
// exceed 2^32). It is read again when its modification time, size or inode changes, and
// refused when group or others may write it (whoever can write it can let anyone in).
//
// ZapHandler lifetime: libzmq admits every CURVE client of a server socket whose context has no
// ZAP handler unless ZMQ_ZAP_ENFORCE_DOMAIN is set; curveServer() sets it (libzmq 4.3 accepts
// it although zmq.h lists it as draft), so without a handler every handshake is refused. Keep
// the ZapHandler alive as long as the server socket all the same.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace zmq {
class context_t;
class socket_t;
}  // namespace zmq

namespace tessera::collab {

/// A key file, allow list or key argument that cannot be used. what() names the file (and line)
/// and why.
struct KeyError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A CURVE key pair, Z85 (40 characters each).
struct KeyPair {
  std::string public_key, secret_key;
};

/// A fresh key pair (zmq_curve_keypair).
KeyPair generateKeyPair();

/// Writes `keys` to `path` with mode 0600, through a temporary file renamed into place. Refuses
/// an existing file (KeyError naming it): a key is never overwritten by accident.
void writeKeyFile(const std::filesystem::path& path, const KeyPair& keys);

/// Reads a key file. KeyError when it is missing, not a regular file, readable or writable by
/// group or others ("site.key: readable by others (mode 0644): chmod 600 site.key"), or when a
/// key is missing, malformed or the public key does not belong to the secret key.
KeyPair readKeyFile(const std::filesystem::path& path);

/// A public key given on a command line: 40 Z85 characters, or a file holding one (a key file's
/// `public = ` line, or the key alone). KeyError naming `what` (the option) otherwise.
std::string readPublicKey(const std::string& argument, const std::string& what);

/// True for 40 characters of the Z85 alphabet that decode to 32 bytes.
bool isZ85Key(const std::string& key);

/// The allow list of site public keys (file format above).
class AllowList {
 public:
  /// Reads `path`. KeyError naming the file and line for a malformed key.
  explicit AllowList(std::filesystem::path path);

  /// Reads the file again if its modification time or size changed since the last read. A file
  /// that became malformed or unreadable keeps the previous list (and the reason is returned,
  /// once per change); returns std::nullopt when nothing went wrong.
  std::optional<std::string> reload();

  /// The name given to `public_key` on its line ("" when none), or std::nullopt when the key
  /// is not on the list.
  std::optional<std::string> find(const std::string& public_key) const;
  size_t size() const;
  /// Increments whenever reload() took a changed list.
  uint64_t generation() const;
  const std::filesystem::path& path() const;

 private:
  struct Impl;
  std::shared_ptr<Impl> m;
};

/// What the ZAP handler decided so far (for messages and tests).
struct ZapCounters {
  uint64_t allowed = 0, refused_unknown_key = 0, refused_mechanism = 0, malformed = 0;
  /// A request for another ZAP domain than "tessera" (another socket of the context).
  uint64_t refused_domain = 0;
};

/// The ZAP handler (RFC 27) of `context`: a thread answering inproc://zeromq.zap.01 for every
/// CURVE server socket of the context with ZMQ_ZAP_DOMAIN "tessera". CURVE clients whose key is
/// on the allow list (reloaded before each decision) pass, with User-Id = their Z85 public key;
/// everything else is refused (status 400), and a line says who and why on stderr, at most one
/// per second per reason. Stops and joins in its destructor. Create it before binding the
/// server socket.
class ZapHandler {
 public:
  ZapHandler(zmq::context_t& context, std::shared_ptr<AllowList> allow);
  ~ZapHandler();
  ZapHandler(const ZapHandler&) = delete;
  ZapHandler& operator=(const ZapHandler&) = delete;
  ZapCounters counters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

/// Makes `socket` a CURVE server with `keys` and ZAP domain "tessera" (before bind()).
void curveServer(zmq::socket_t& socket, const KeyPair& keys);
/// Makes `socket` a CURVE client with its own `keys`, trusting `server_public_key` (before
/// connect()).
void curveClient(zmq::socket_t& socket, const KeyPair& keys, const std::string& server_public_key);

}  // namespace tessera::collab
