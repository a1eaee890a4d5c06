// A small strict JSON reader and the writing helpers the annotation export needs (no JSON
// library is among the project's packages). RFC 8259 only: no comments, no trailing commas, no
// NaN; duplicate keys and nesting deeper than a bound are refused, so what an import reads has
// one meaning.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace tessera::annotate::json {

/// A parse failure; the message says where ("byte 120: expected ':'").
class ParseError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Member;

struct Value {
  enum class Type { kNull, kBool, kNumber, kString, kArray, kObject };
  Type type = Type::kNull;
  bool boolean = false;
  std::string text;  ///< a string's contents (UTF-8), or a number's literal as written
  std::vector<Value> array;
  std::vector<Member> object;  ///< in file order

  /// The member named `key`, or nullptr.
  const Value* find(std::string_view key) const;
};

struct Member {
  std::string key;
  Value value;
};

inline const Value* Value::find(std::string_view key) const {
  for (const Member& m : object)
    if (m.key == key) return &m.value;
  return nullptr;
}

const char* typeName(Value::Type type);

/// Parses one JSON document (whitespace around it allowed). Throws ParseError. Cost linear in
/// the size; nesting deeper than `max_depth` is refused (no stack overflow on hostile input).
Value parse(std::string_view text, int max_depth = 32);

/// The shortest decimal text that reads back as exactly `v` (std::to_chars); v must be finite.
std::string number(double v);

/// RFC 4648 base64 with padding; decode returns false on anything else.
std::string base64Encode(const std::vector<uint8_t>& bytes);
bool base64Decode(std::string_view text, std::vector<uint8_t>& out);

}  // namespace tessera::annotate::json
