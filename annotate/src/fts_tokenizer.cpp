#include "fts_tokenizer.h"

#include <cstddef>
#include <cstdint>
#include <new>
#include <vector>

namespace tessera::annotate::detail {
namespace {

enum class Class { kOther, kSpaceless, kSymbol, kJoiner };

/// Scripts written without spaces between words: Thai, Lao, Myanmar, Khmer, CJK radicals,
/// ideographic iteration marks, kana, bopomofo, the CJK ideographs and their extensions,
/// halfwidth katakana.
bool spaceless(uint32_t c) {
  return (c >= 0x0E00 && c <= 0x0EFF) || (c >= 0x1000 && c <= 0x109F) ||
         (c >= 0x1780 && c <= 0x17FF) || (c >= 0x2E80 && c <= 0x2FDF) ||
         (c >= 0x3005 && c <= 0x3007) || (c >= 0x3021 && c <= 0x3029) ||
         (c >= 0x3031 && c <= 0x3035) || (c >= 0x3041 && c <= 0x30FA) ||
         (c >= 0x30FC && c <= 0x30FF) || (c >= 0x3100 && c <= 0x312F) ||
         (c >= 0x31A0 && c <= 0x31BF) || (c >= 0x31F0 && c <= 0x31FF) ||
         (c >= 0x3400 && c <= 0x4DBF) || (c >= 0x4E00 && c <= 0x9FFF) ||
         (c >= 0xF900 && c <= 0xFAFF) || (c >= 0xFF66 && c <= 0xFF9F) ||
         (c >= 0x20000 && c <= 0x323AF);
}

/// Symbols unicode61 drops as separators: arrows, technical symbols, enclosed alphanumerics,
/// geometric shapes, dingbats, supplemental arrows, miscellaneous symbols, pictographs, emoji.
bool symbol(uint32_t c) {
  return (c >= 0x2190 && c <= 0x21FF) || (c >= 0x2300 && c <= 0x23FF) ||
         (c >= 0x2460 && c <= 0x24FF) || (c >= 0x25A0 && c <= 0x27BF) ||
         (c >= 0x2900 && c <= 0x297F) || (c >= 0x2B00 && c <= 0x2BFF) || c == 0x3297 ||
         c == 0x3299 || (c >= 0x1F000 && c <= 0x1F3FA) || (c >= 0x1F400 && c <= 0x1FAFF);
}

/// What joins or dresses a symbol without being one: zero width joiner, variation selectors,
/// skin-tone modifiers, tag characters. Separators here, so 👍🏽 finds 👍.
bool joiner(uint32_t c) {
  return c == 0x200D || (c >= 0xFE00 && c <= 0xFE0F) || (c >= 0x1F3FB && c <= 0x1F3FF) ||
         (c >= 0xE0020 && c <= 0xE007F);
}

Class classOf(uint32_t c) {
  if (c < 0x0E00) return Class::kOther;
  if (spaceless(c)) return Class::kSpaceless;
  if (joiner(c)) return Class::kJoiner;
  if (symbol(c)) return Class::kSymbol;
  return Class::kOther;
}

/// The code point at text[i] and its length in bytes; a malformed byte reads as itself (1).
uint32_t decode(const char* text, int n, int i, int* length) {
  const auto b = [&](int k) { return static_cast<unsigned char>(text[k]); };
  const unsigned c = b(i);
  int len = c < 0x80             ? 1
            : (c & 0xE0) == 0xC0 ? 2
            : (c & 0xF0) == 0xE0 ? 3
            : (c & 0xF8) == 0xF0 ? 4
                                 : 1;
  if (i + len > n) len = 1;
  uint32_t cp = len == 1 ? c : len == 2 ? (c & 0x1F) : len == 3 ? (c & 0x0F) : (c & 0x07);
  for (int k = 1; k < len; ++k) {
    if ((b(i + k) & 0xC0) != 0x80) {
      *length = 1;
      return c;
    }
    cp = (cp << 6) | (b(i + k) & 0x3F);
  }
  *length = len;
  return cp;
}

struct Tokenizer {
  fts5_tokenizer words_api{};
  Fts5Tokenizer* words = nullptr;  ///< unicode61 (remove_diacritics 2)
};

using TokenCallback = int (*)(void*, int, const char*, int, int, int);

/// unicode61's tokens of a run of other text, their offsets moved to the whole text's.
struct Shifted {
  void* ctx;
  TokenCallback token;
  int offset;
};

int shiftedToken(void* p, int flags, const char* token, int n, int start, int end) {
  const auto* s = static_cast<Shifted*>(p);
  return s->token(s->ctx, flags, token, n, start + s->offset, end + s->offset);
}

int create(void* context, const char**, int, Fts5Tokenizer** out) {
  auto* api = static_cast<fts5_api*>(context);
  void* user = nullptr;
  auto* t = new (std::nothrow) Tokenizer;
  if (!t) return SQLITE_NOMEM;
  int rc = api->xFindTokenizer(api, "unicode61", &user, &t->words_api);
  const char* args[] = {"remove_diacritics", "2"};
  if (rc == SQLITE_OK) rc = t->words_api.xCreate(user, args, 2, &t->words);
  if (rc != SQLITE_OK) {
    delete t;
    return rc;
  }
  *out = reinterpret_cast<Fts5Tokenizer*>(t);
  return SQLITE_OK;
}

void destroy(Fts5Tokenizer* p) {
  auto* t = reinterpret_cast<Tokenizer*>(p);
  if (t->words) t->words_api.xDelete(t->words);
  delete t;
}

int tokenize(Fts5Tokenizer* p, void* ctx, int flags, const char* text, int n, TokenCallback token) {
  auto* t = reinterpret_cast<Tokenizer*>(p);
  const bool query = (flags & FTS5_TOKENIZE_QUERY) != 0;
  int other_start = 0;  ///< the run of other text not yet handed to unicode61
  auto flushOther = [&](int end) {
    if (end <= other_start) return SQLITE_OK;
    Shifted s{ctx, token, other_start};
    return t->words_api.xTokenize(t->words, &s, flags, text + other_start, end - other_start,
                                  shiftedToken);
  };
  std::vector<int> starts;  ///< byte offsets of a spaceless run's characters, and its end
  int i = 0;
  while (i < n) {
    int len = 1;
    const Class c = classOf(decode(text, n, i, &len));
    if (c == Class::kOther) {
      i += len;
      continue;
    }
    if (const int rc = flushOther(i); rc != SQLITE_OK) return rc;
    if (c == Class::kSymbol) {
      if (const int rc = token(ctx, 0, text + i, len, i, i + len); rc != SQLITE_OK) return rc;
      i += len;
    } else if (c == Class::kJoiner) {
      i += len;
    } else {
      starts.clear();
      while (i < n) {
        int l = 1;
        if (classOf(decode(text, n, i, &l)) != Class::kSpaceless) break;
        starts.push_back(i);
        i += l;
      }
      starts.push_back(i);
      const size_t chars = starts.size() - 1;
      for (size_t k = 0; k < chars; ++k) {
        const int a = starts[k], b = starts[k + 1];
        const bool pair = k + 1 < chars;
        const int e = pair ? starts[k + 2] : b;
        int rc = SQLITE_OK;
        if (query) {
          // The phrase of the query's bigrams (or the one character): any substring matches.
          if (pair)
            rc = token(ctx, 0, text + a, e - a, a, e);
          else if (chars == 1)
            rc = token(ctx, 0, text + a, b - a, a, b);
        } else {
          // The bigram first: a match is highlighted over the first token at its position.
          rc = pair ? token(ctx, 0, text + a, e - a, a, e) : token(ctx, 0, text + a, b - a, a, b);
          if (rc == SQLITE_OK && pair) rc = token(ctx, FTS5_TOKEN_COLOCATED, text + a, b - a, a, b);
        }
        if (rc != SQLITE_OK) return rc;
      }
    }
    other_start = i;
  }
  return flushOther(n);
}

fts5_api* fts5Of(sqlite3* db) {
  fts5_api* api = nullptr;
  sqlite3_stmt* s = nullptr;
  if (sqlite3_prepare_v2(db, "SELECT fts5(?1)", -1, &s, nullptr) == SQLITE_OK) {
    sqlite3_bind_pointer(s, 1, static_cast<void*>(&api), "fts5_api_ptr", nullptr);
    sqlite3_step(s);
  }
  sqlite3_finalize(s);
  return api;
}

}  // namespace

int registerTokenizer(sqlite3* db) {
  fts5_api* api = fts5Of(db);
  if (!api || api->iVersion < 2) return SQLITE_ERROR;
  fts5_tokenizer t{create, destroy, tokenize};
  return api->xCreateTokenizer(api, kTokenizerName, api, &t, nullptr);
}

}  // namespace tessera::annotate::detail
