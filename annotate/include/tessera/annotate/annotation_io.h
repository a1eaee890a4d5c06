// Exports and imports of the annotation database (CSV, JSON, GeoJSON), used by
// tessera-annotate. Imports are outside bytes: everything is validated, an error names the file
// and the field ("importJson(): notes.json: items[3].position[1]: expected a finite number"),
// and a file with any error imports nothing (one transaction).
#pragma once

#include <cstddef>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <utility>

#include <glm/vec3.hpp>

#include <tessera/annotate/annotation_db.h>

namespace tessera::annotate {

/// Everything in the database as one JSON document (format "tessera-annotations", version 2):
/// layers with visibility, items (embedded images and selections in base64), places,
/// attachments [item, place] and the georeference. Doubles are written in their shortest exact
/// form, so importJson() into an empty database and exporting again gives the same bytes.
void exportJson(AnnotationDb& db, std::ostream& out);

/// One row per item of `layer` and its sublayers ("" for all), RFC 4180 quoting, times in UTC
/// ISO 8601; the first point or hot spot the item hangs at in x, y, z (local frame, metres);
/// embedded image bytes are not written (data_bytes gives their size). A text field that begins
/// like a spreadsheet formula (= + - @, tab, carriage return) is written with a leading
/// apostrophe, so that opening the file in a spreadsheet runs nothing a participant typed.
void exportCsv(AnnotationDb& db, std::ostream& out, const std::string& layer = "");

/// A georeference: a projected CRS in metres ("EPSG:32633") and the CRS coordinates of the
/// store's local origin.
struct Georeference {
  std::string crs;
  glm::dvec3 origin{0.0};
};

/// Points and hot spots as GeoJSON Point features (x, y, z = origin + local position, metres in
/// `geo.crs`, named in a "crs" member as GeoJSON 2008 did: RFC 7946 allows other CRSs than
/// WGS 84 only by agreement, which this member records), with their items as properties.
/// Selections have no single position and are left out. `geo` defaults to the database's
/// georeference; with neither, throws AnnotationError kBadInput: a local frame is not a place
/// on Earth. Geographic CRSs (EPSG:4326, CRS84...) are refused: metres cannot be added to
/// degrees.
void exportGeoJson(AnnotationDb& db, std::ostream& out,
                   const std::optional<Georeference>& geo = std::nullopt);

struct ImportCounts {
  size_t layers = 0, items = 0, places = 0, attachments = 0;
};

/// Imports a JSON export. Into an empty database (no items, no places) ids are kept, so the
/// round trip is exact; otherwise items and places get new ids after the existing ones and
/// links and attachments follow them. Authors, times and revisions are kept; the file's layer
/// visibility and georeference (when not null) replace the database's. `name` is the
/// file name used in messages. Throws AnnotationError (kBadInput for a malformed file).
ImportCounts importJson(AnnotationDb& db, std::string_view bytes, const std::string& name);

}  // namespace tessera::annotate
