// Small pieces shared by the format readers: error messages, endian loads, number parsing.
#pragma once

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include <tessera/lod/point_reader.h>

namespace tessera::lod::detail {

/// Throws ReadError "component: file: where: what".
[[noreturn]] inline void fail(const char* component, const std::string& file,
                              const std::string& where, const std::string& what) {
  std::string msg = std::string(component) + ": " + file;
  if (!where.empty()) msg += ": " + where;
  throw ReadError(msg + ": " + what);
}

inline std::string atByte(uint64_t offset) {
  return "byte " + std::to_string(offset);
}
inline std::string atLine(uint64_t line) {
  return "line " + std::to_string(line);
}

/// Loads a T stored little- (swap=false on this little-endian host) or big-endian.
template <typename T>
inline T load(const uint8_t* p, bool swap) {
  static_assert(std::endian::native == std::endian::little, "little-endian hosts only");
  T v;
  std::memcpy(&v, p, sizeof(T));
  if (swap && sizeof(T) > 1) {
    uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    std::memcpy(&v, b, sizeof(T));
  }
  return v;
}

template <typename T>
inline T loadLE(const uint8_t* p) {
  return load<T>(p, false);
}

/// Parses a whole token as a double ("1e-3", "nan", "inf" accepted). False if not a number.
inline bool parseDouble(std::string_view s, double& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && !s.empty();
}

/// Parses a whole token as an unsigned integer.
inline bool parseUint(std::string_view s, uint64_t& out) {
  auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && !s.empty();
}

/// Splits off the next token separated by any of `seps`; empty when none is left.
inline std::string_view nextToken(std::string_view& s, std::string_view seps = " \t") {
  size_t b = s.find_first_not_of(seps);
  if (b == std::string_view::npos) {
    s = {};
    return {};
  }
  size_t e = s.find_first_of(seps, b);
  std::string_view tok = s.substr(b, e == std::string_view::npos ? std::string_view::npos : e - b);
  s = e == std::string_view::npos ? std::string_view{} : s.substr(e);
  return tok;
}

inline bool finite3(double x, double y, double z) {
  return std::isfinite(x) && std::isfinite(y) && std::isfinite(z);
}

/// Text shown for a token in messages: quoted, cut to 40 characters.
inline std::string shown(std::string_view tok) {
  std::string s(tok.substr(0, 40));
  for (char& c : s) {
    if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
  }
  return "'" + s + (tok.size() > 40 ? "...'" : "'");
}

}  // namespace tessera::lod::detail
