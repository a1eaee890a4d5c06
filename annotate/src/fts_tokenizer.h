// The full-text index's tokenizer, "tessera": words in any script. FTS5's unicode61 splits text
// at spaces and punctuation, which finds words in Latin, Greek, Cyrillic, Arabic or Korean but
// nothing inside a Japanese or Chinese sentence (written without spaces), and it drops emoji
// and symbols as separators. This one hands unicode61 the runs of such text and, itself:
// - indexes the scripts written without spaces (Han, kana, Thai, Lao, Khmer, Myanmar) as
//   overlapping bigrams, each character at its own position with the bigram it starts
//   colocated there; a query of two or more such characters becomes the phrase of its
//   bigrams, so any substring matches (東京 inside 東京の調査で...), and a single character
//   matches as itself;
// - indexes every symbol or emoji (arrows, dingbats, pictographs) as a token of its own, so
//   🐇 finds its note.
// Phrases, prefixes, column filters (title:) and AND / OR / NOT work as with unicode61.
#pragma once

#include <sqlite3.h>

namespace tessera::annotate::detail {

/// The name the tokenizer is registered under (CREATE VIRTUAL TABLE ... tokenize='tessera').
inline constexpr const char* kTokenizerName = "tessera";

/// Registers the tokenizer on `db` (every connection needs it before the index is used).
/// Returns an SQLite result code.
int registerTokenizer(sqlite3* db);

}  // namespace tessera::annotate::detail
