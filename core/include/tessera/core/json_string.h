// JSON string literals: the one escaper every writer of JSON uses (stores' summaries, the
// annotation exports, tools' --json outputs).
#pragma once

#include <string>
#include <string_view>

namespace tessera {

/// Appends `s` as a JSON string literal: quoted, with ", \ and the control characters (below
/// 0x20, and DEL) escaped (\n, \r, \t by name, the rest as \u00XX). Bytes of 0x80 and above
/// pass unchanged, so UTF-8 stays UTF-8.
void appendJsonString(std::string& out, std::string_view s);

/// `s` as a JSON string literal (appendJsonString()).
std::string jsonString(std::string_view s);

}  // namespace tessera
