// The body of the annotation import fuzz target and its regression replay: the bytes are a JSON
// export (annotate/src/annotation_io.cpp) imported into a fresh database in memory. AnnotationError
// is the only failure allowed; a file that imports must export, import into another empty
// database and export again to the same bytes (the exact round trip the format promises).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string_view>

#include <tessera/annotate/annotation_db.h>
#include <tessera/annotate/annotation_io.h>

namespace tessera::fuzz {

inline void requireAnnotation(bool ok, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "annotation fuzz: broken invariant: %s\n", what);
  std::abort();
}

inline int importAnnotations(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  annotate::AnnotationDb db(":memory:");
  try {
    annotate::importJson(db, bytes, "fuzz.json");
  } catch (const annotate::AnnotationError&) {
    requireAnnotation(db.items().empty() && db.places().empty() && db.layers().empty(),
                      "a refused import left data behind");
    return 0;
  }
  std::ostringstream first, second;
  annotate::exportJson(db, first);
  annotate::AnnotationDb copy(":memory:");
  annotate::importJson(copy, first.str(), "export.json");  // must not throw
  annotate::exportJson(copy, second);
  requireAnnotation(first.str() == second.str(), "export -> import -> export is not exact");
  requireAnnotation(db.integrityCheck() == "ok", "integrity_check failed after an import");
  return 0;
}

}  // namespace tessera::fuzz
