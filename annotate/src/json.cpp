#include "json.h"

#include <cassert>
#include <charconv>
#include <cmath>
#include <cstdio>

#include "utf8.h"

namespace tessera::annotate::json {

namespace {

class Parser {
 public:
  Parser(std::string_view text, int max_depth) : mText(text), mMaxDepth(max_depth) {}

  Value document() {
    skipSpace();
    Value v = value(0);
    skipSpace();
    if (mPos != mText.size()) fail("unexpected text after the document");
    return v;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw ParseError("byte " + std::to_string(mPos) + ": " + what);
  }
  bool atEnd() const { return mPos >= mText.size(); }
  char peek() const { return atEnd() ? '\0' : mText[mPos]; }
  void skipSpace() {
    while (!atEnd() && (peek() == ' ' || peek() == '\t' || peek() == '\n' || peek() == '\r'))
      ++mPos;
  }
  void expect(char c) {
    if (peek() != c || atEnd()) fail(std::string("expected '") + c + "'");
    ++mPos;
  }
  void literal(std::string_view word) {
    if (mText.substr(mPos, word.size()) != word) fail("expected a value");
    mPos += word.size();
  }

  Value value(int depth) {
    if (depth > mMaxDepth) fail("nested deeper than " + std::to_string(mMaxDepth) + " levels");
    Value v;
    switch (peek()) {
      case '{':
        object(v, depth);
        break;
      case '[':
        array(v, depth);
        break;
      case '"':
        v.type = Value::Type::kString;
        v.text = string();
        break;
      case 't':
        literal("true");
        v.type = Value::Type::kBool;
        v.boolean = true;
        break;
      case 'f':
        literal("false");
        v.type = Value::Type::kBool;
        break;
      case 'n':
        literal("null");
        break;
      default:
        number(v);
    }
    return v;
  }

  void object(Value& v, int depth) {
    v.type = Value::Type::kObject;
    ++mPos;
    skipSpace();
    if (peek() == '}' && !atEnd()) {
      ++mPos;
      return;
    }
    for (;;) {
      skipSpace();
      if (peek() != '"' || atEnd()) fail("expected a key string");
      std::string key = string();
      if (v.find(key)) fail("duplicate key \"" + key + "\"");
      skipSpace();
      expect(':');
      skipSpace();
      v.object.push_back(Member{std::move(key), value(depth + 1)});
      skipSpace();
      if (peek() == ',' && !atEnd()) {
        ++mPos;
        continue;
      }
      expect('}');
      return;
    }
  }

  void array(Value& v, int depth) {
    v.type = Value::Type::kArray;
    ++mPos;
    skipSpace();
    if (peek() == ']' && !atEnd()) {
      ++mPos;
      return;
    }
    for (;;) {
      skipSpace();
      v.array.push_back(value(depth + 1));
      skipSpace();
      if (peek() == ',' && !atEnd()) {
        ++mPos;
        continue;
      }
      expect(']');
      return;
    }
  }

  unsigned hex4() {
    if (mPos + 4 > mText.size()) fail("truncated \\u escape");
    unsigned cp = 0;
    for (int i = 0; i < 4; ++i) {
      const char c = mText[mPos++];
      cp <<= 4;
      if (c >= '0' && c <= '9')
        cp |= unsigned(c - '0');
      else if (c >= 'a' && c <= 'f')
        cp |= unsigned(c - 'a' + 10);
      else if (c >= 'A' && c <= 'F')
        cp |= unsigned(c - 'A' + 10);
      else
        fail("bad hex digit in a \\u escape");
    }
    return cp;
  }

  static void appendUtf8(std::string& out, unsigned cp) {
    if (cp < 0x80) {
      out += char(cp);
    } else if (cp < 0x800) {
      out += char(0xc0 | (cp >> 6));
      out += char(0x80 | (cp & 0x3f));
    } else if (cp < 0x10000) {
      out += char(0xe0 | (cp >> 12));
      out += char(0x80 | ((cp >> 6) & 0x3f));
      out += char(0x80 | (cp & 0x3f));
    } else {
      out += char(0xf0 | (cp >> 18));
      out += char(0x80 | ((cp >> 12) & 0x3f));
      out += char(0x80 | ((cp >> 6) & 0x3f));
      out += char(0x80 | (cp & 0x3f));
    }
  }

  std::string string() {
    ++mPos;  // the opening quote
    std::string out;
    const size_t start = mPos;
    for (;;) {
      if (atEnd()) fail("unterminated string");
      const char c = mText[mPos++];
      if (c == '"') break;
      if (static_cast<unsigned char>(c) < 0x20) fail("control character in a string");
      if (c != '\\') {
        out += c;
        continue;
      }
      if (atEnd()) fail("unterminated escape");
      const char e = mText[mPos++];
      switch (e) {
        case '"':
          out += '"';
          break;
        case '\\':
          out += '\\';
          break;
        case '/':
          out += '/';
          break;
        case 'b':
          out += '\b';
          break;
        case 'f':
          out += '\f';
          break;
        case 'n':
          out += '\n';
          break;
        case 'r':
          out += '\r';
          break;
        case 't':
          out += '\t';
          break;
        case 'u': {
          unsigned cp = hex4();
          if (cp >= 0xdc00 && cp <= 0xdfff) fail("lone low surrogate in a \\u escape");
          if (cp >= 0xd800 && cp <= 0xdbff) {
            if (mText.substr(mPos, 2) != "\\u") fail("lone high surrogate in a \\u escape");
            mPos += 2;
            const unsigned lo = hex4();
            if (lo < 0xdc00 || lo > 0xdfff) fail("bad surrogate pair in a \\u escape");
            cp = 0x10000 + ((cp - 0xd800) << 10) + (lo - 0xdc00);
          }
          if (cp == 0) fail("\\u0000 in a string");
          appendUtf8(out, cp);
          break;
        }
        default:
          fail(std::string("bad escape '\\") + e + "'");
      }
    }
    if (!detail::validUtf8(out)) {
      mPos = start;
      fail("string is not valid UTF-8");
    }
    return out;
  }

  void number(Value& v) {
    // RFC 8259: -?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?
    const size_t start = mPos;
    auto digits = [&] {
      const size_t from = mPos;
      while (!atEnd() && peek() >= '0' && peek() <= '9') ++mPos;
      return mPos - from;
    };
    if (peek() == '-') ++mPos;
    if (peek() == '0' && !atEnd())
      ++mPos;
    else if (digits() == 0)
      fail("expected a value");
    if (peek() == '.' && !atEnd()) {
      ++mPos;
      if (digits() == 0) fail("expected digits after '.'");
    }
    if ((peek() == 'e' || peek() == 'E') && !atEnd()) {
      ++mPos;
      if (peek() == '+' || peek() == '-') ++mPos;
      if (digits() == 0) fail("expected digits in the exponent");
    }
    v.type = Value::Type::kNumber;
    v.text = std::string(mText.substr(start, mPos - start));
  }

  std::string_view mText;
  int mMaxDepth;
  size_t mPos = 0;
};

constexpr char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

}  // namespace

const char* typeName(Value::Type type) {
  switch (type) {
    case Value::Type::kNull:
      return "null";
    case Value::Type::kBool:
      return "a boolean";
    case Value::Type::kNumber:
      return "a number";
    case Value::Type::kString:
      return "a string";
    case Value::Type::kArray:
      return "an array";
    case Value::Type::kObject:
      return "an object";
  }
  return "?";
}

Value parse(std::string_view text, int max_depth) {
  return Parser(text, max_depth).document();
}

std::string number(double v) {
  assert(std::isfinite(v));
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  assert(ec == std::errc());
  (void)ec;
  return std::string(buf, end);
}

std::string base64Encode(const std::vector<uint8_t>& bytes) {
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const unsigned n = bytes.size() - i;
    const unsigned w = (unsigned(bytes[i]) << 16) | (n > 1 ? unsigned(bytes[i + 1]) << 8 : 0u) |
                       (n > 2 ? unsigned(bytes[i + 2]) : 0u);
    out += kBase64[(w >> 18) & 63];
    out += kBase64[(w >> 12) & 63];
    out += n > 1 ? kBase64[(w >> 6) & 63] : '=';
    out += n > 2 ? kBase64[w & 63] : '=';
  }
  return out;
}

bool base64Decode(std::string_view text, std::vector<uint8_t>& out) {
  out.clear();
  if (text.size() % 4 != 0) return false;
  auto index = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  out.reserve(text.size() / 4 * 3);
  for (size_t i = 0; i < text.size(); i += 4) {
    const bool last = i + 4 == text.size();
    const int pad = last ? (text[i + 3] == '=') + (text[i + 2] == '=') : 0;
    if (pad == 1 && text[i + 2] == '=') return false;  // "x=y=" is not padding
    unsigned w = 0;
    for (int k = 0; k < 4 - pad; ++k) {
      const int d = index(text[i + k]);
      if (d < 0) return false;
      w = (w << 6) | unsigned(d);
    }
    w <<= 6 * pad;
    out.push_back(uint8_t(w >> 16));
    if (pad < 2) out.push_back(uint8_t(w >> 8));
    if (pad < 1) out.push_back(uint8_t(w));
    // Canonical form only: the bits under the padding must be zero, so each byte string has
    // one encoding and an import writes back exactly what it read.
    if ((pad == 1 && (w & 0xff)) || (pad == 2 && (w & 0xffff))) return false;
  }
  return true;
}

}  // namespace tessera::annotate::json
