#include <tessera/annotate/annotation_io.h>

#include <proj.h>
#include <sqlite3.h>

#include <tessera/core/json_string.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <ctime>
#include <map>
#include <set>

#include "json.h"

namespace tessera::annotate {

namespace {

using json::Value;

constexpr const char* kFormat = "tessera-annotations";
constexpr int kFormatVersion = 2;

std::string vec(const glm::dvec3& v) {
  return "[" + json::number(v.x) + ", " + json::number(v.y) + ", " + json::number(v.z) + "]";
}

std::string viewJson(const StoredView& v, const glm::dvec3& offset = glm::dvec3(0.0)) {
  return "{\"eye\": " + vec(v.eye + offset) + ", \"target\": " + vec(v.target + offset) +
         ", \"up\": " + vec(v.up) + ", \"fovy_deg\": " + json::number(v.fovy_deg) + "}";
}

std::string itemJson(const Item& it) {
  std::string s = "{\"id\": " + std::to_string(it.id) + ", \"layer\": " + jsonString(it.layer) +
                  ", \"kind\": " + jsonString(toString(it.kind)) +
                  ", \"title\": " + jsonString(it.title) + ", \"text\": " + jsonString(it.text);
  switch (it.kind) {
    case ItemKind::kText:
      break;
    case ItemKind::kNumber:
      s += ", \"number\": " + json::number(it.number) + ", \"unit\": " + jsonString(it.unit);
      break;
    case ItemKind::kImage:
      s += ", \"mime\": " + jsonString(it.mime);
      s += it.path.empty() ? ", \"data\": " + jsonString(json::base64Encode(it.data))
                           : ", \"path\": " + jsonString(it.path);
      break;
    case ItemKind::kLink:
      s += it.link_item ? ", \"link_item\": " + std::to_string(it.link_item)
                        : ", \"link_uri\": " + jsonString(it.link_uri);
      break;
  }
  s += ", \"author\": " + jsonString(it.author) +
       ", \"created_us\": " + std::to_string(it.created_us) +
       ", \"modified_us\": " + std::to_string(it.modified_us) +
       ", \"revision\": " + std::to_string(it.revision) + "}";
  return s;
}

std::string placeJson(const Place& p) {
  std::string s = "{\"id\": " + std::to_string(p.id) +
                  ", \"kind\": " + jsonString(toString(p.kind)) +
                  ", \"model\": " + jsonString(p.model) + ", \"position\": " + vec(p.position);
  if (p.kind == PlaceKind::kHotSpot) s += ", \"radius\": " + json::number(p.radius);
  if (p.view) s += ", \"view\": " + viewJson(*p.view);
  if (p.kind == PlaceKind::kSelection)
    s += ", \"selection_id\": " + jsonString(p.selection_id) +
         ", \"selection\": " + jsonString(json::base64Encode(p.selection));
  return s + "}";
}

/// Every (item, place) pair, by item then place.
std::vector<std::pair<int64_t, int64_t>> attachments(AnnotationDb& db) {
  std::vector<std::pair<int64_t, int64_t>> out;
  for (const Place& p : db.places())
    for (int64_t item : db.itemsAt(p.id)) out.emplace_back(item, p.id);
  std::sort(out.begin(), out.end());
  return out;
}

std::string isoTime(int64_t us) {
  const std::time_t seconds = std::time_t(us / 1000000);
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  char buf[40];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  char frac[16];
  std::snprintf(frac, sizeof frac, ".%06dZ", int(us % 1000000));
  return std::string(buf) + frac;
}

/// RFC 4180: quoted when it holds a comma, quote or line break; quotes doubled. Text that a
/// spreadsheet would take for a formula (it begins with = + - @, a tab or a carriage return:
/// "=HYPERLINK(...)" typed into a note at a remote site) gets a leading apostrophe and quotes
/// (OWASP's advice against CSV injection), so opening the export runs nothing.
std::string csvField(const std::string& s) {
  const bool formula = !s.empty() && std::string_view("=+-@\t\r").find(s[0]) != std::string::npos;
  if (!formula && s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string out = formula ? "\"'" : "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

// --- Import ---------------------------------------------------------------------------------

/// Reads fields of one JSON object, naming the file and the field's path in every error, and
/// refusing keys it was not asked for (a misspelt key is an error, not silently dropped).
class Fields {
 public:
  Fields(const Value& v, std::string path, const std::string& file)
      : mValue(v), mPath(std::move(path)), mFile(file) {
    if (v.type != Value::Type::kObject) fail(mPath, "expected an object");
  }

  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          "importJson(): " + mFile + ": " + path + ": " + what);
  }
  std::string at(const char* key) const { return mPath + "." + key; }

  const Value* optional(const char* key) {
    mUsed.insert(key);
    return mValue.find(key);
  }
  const Value& required(const char* key, Value::Type type) {
    const Value* v = optional(key);
    if (!v) fail(at(key), "missing");
    if (v->type != type)
      fail(at(key),
           std::string("expected ") + json::typeName(type) + ", found " + json::typeName(v->type));
    return *v;
  }
  std::string string(const char* key) { return required(key, Value::Type::kString).text; }
  std::string string(const char* key, const std::string& fallback) {
    return optional(key) ? string(key) : fallback;
  }
  bool boolean(const char* key) { return required(key, Value::Type::kBool).boolean; }
  int64_t integer(const char* key) {
    return toInteger(required(key, Value::Type::kNumber), at(key));
  }
  int64_t toInteger(const Value& v, const std::string& path) const {
    int64_t out = 0;
    const auto [end, ec] = std::from_chars(v.text.data(), v.text.data() + v.text.size(), out);
    if (ec != std::errc() || end != v.text.data() + v.text.size())
      fail(path, "expected an integer in [-2^63, 2^63), found " + v.text.substr(0, 40));
    return out;
  }
  double toReal(const Value& v, const std::string& path) const {
    if (v.type != Value::Type::kNumber) fail(path, "expected a finite number");
    double out = 0;
    const auto [end, ec] = std::from_chars(v.text.data(), v.text.data() + v.text.size(), out);
    if (ec != std::errc() || end != v.text.data() + v.text.size() || !std::isfinite(out))
      fail(path, "expected a finite number, found " + v.text.substr(0, 40));
    return out;
  }
  double real(const char* key) { return toReal(required(key, Value::Type::kNumber), at(key)); }
  glm::dvec3 vec3(const char* key) {
    const Value& a = required(key, Value::Type::kArray);
    if (a.array.size() != 3) fail(at(key), "expected [x, y, z]");
    glm::dvec3 out;
    for (int i = 0; i < 3; ++i)
      out[i] = toReal(a.array[size_t(i)], at(key) + "[" + std::to_string(i) + "]");
    return out;
  }
  std::vector<uint8_t> base64(const char* key) {
    std::vector<uint8_t> out;
    if (!json::base64Decode(string(key), out)) fail(at(key), "expected canonical base64");
    return out;
  }
  /// Call after reading: any key not asked for is an error.
  void done() const {
    for (const auto& [k, v] : mValue.object)
      if (!mUsed.count(k)) fail(mPath + "." + k, "unknown field");
  }

 private:
  const Value& mValue;
  std::string mPath;
  const std::string& mFile;
  std::set<std::string> mUsed;
};

const Value& arrayField(Fields& f, const char* key) {
  return f.required(key, Value::Type::kArray);
}

/// Re-throws a database error about an imported element with the element's path in front.
template <typename F>
auto withPath(const std::string& file, const std::string& path, F&& body) {
  try {
    return body();
  } catch (const AnnotationError& e) {
    throw AnnotationError(e.kind(), "importJson(): " + file + ": " + path + ": " + e.what());
  }
}

int64_t nextId(AnnotationDb& db, const char* table) {
  // AUTOINCREMENT's high-water mark, so new ids never reuse a removed one.
  const std::string sql = std::string("SELECT max(coalesce((SELECT seq FROM sqlite_sequence ") +
                          "WHERE name = '" + table + "'), 0), coalesce((SELECT max(id) FROM " +
                          table + "), 0)) + 1";
  sqlite3_stmt* s = nullptr;
  int64_t next = 1;
  if (sqlite3_prepare_v2(db.handle(), sql.c_str(), -1, &s, nullptr) == SQLITE_OK &&
      sqlite3_step(s) == SQLITE_ROW)
    next = sqlite3_column_int64(s, 0);
  sqlite3_finalize(s);
  return next;
}

}  // namespace

void exportJson(AnnotationDb& db, std::ostream& out) {
  std::string s = "{\n\"format\": " + jsonString(kFormat) +
                  ",\n\"version\": " + std::to_string(kFormatVersion) + ",\n\"georeference\": ";
  if (const auto geo = db.georeference())
    s += "{\"crs\": " + jsonString(geo->first) + ", \"origin\": " + vec(geo->second) + "}";
  else
    s += "null";
  s += ",\n\"layers\": [";
  const std::vector<Layer> layers = db.layers();
  for (size_t i = 0; i < layers.size(); ++i)
    s += std::string(i ? ",\n" : "\n") + "{\"path\": " + jsonString(layers[i].path) +
         ", \"visible\": " + (layers[i].visible ? "true" : "false") + "}";
  s += "\n],\n\"items\": [";
  bool first = true;
  for (const Item& it : db.items()) {
    s += (first ? "\n" : ",\n") + itemJson(it);
    first = false;
  }
  s += "\n],\n\"places\": [";
  first = true;
  for (const Place& p : db.places()) {
    s += (first ? "\n" : ",\n") + placeJson(p);
    first = false;
  }
  s += "\n],\n\"attachments\": [";
  first = true;
  for (const auto& [item, place] : attachments(db)) {
    s += (first ? "\n" : ",\n") + ("[" + std::to_string(item) + ", " + std::to_string(place) + "]");
    first = false;
  }
  s += "\n]\n}\n";
  out << s;
}

void exportCsv(AnnotationDb& db, std::ostream& out, const std::string& layer) {
  out << "id,layer,kind,title,text,number,unit,mime,path,data_bytes,link_item,link_uri,author,"
         "created_utc,modified_utc,revision,places,x,y,z\r\n";
  for (const Item& it : db.items(layer)) {
    std::string places;
    std::optional<glm::dvec3> at;
    for (int64_t id : db.placesOf(it.id)) {
      places += (places.empty() ? "" : ";") + std::to_string(id);
      const auto p = db.place(id);
      if (!at && p && p->kind != PlaceKind::kSelection) at = p->position;
    }
    const bool number = it.kind == ItemKind::kNumber;
    out << it.id << ',' << csvField(it.layer) << ',' << toString(it.kind) << ','
        << csvField(it.title) << ',' << csvField(it.text) << ','
        << (number ? json::number(it.number) : "") << ',' << csvField(it.unit) << ','
        << csvField(it.mime) << ',' << csvField(it.path) << ','
        << (it.data.empty() ? "" : std::to_string(it.data.size())) << ','
        << (it.link_item ? std::to_string(it.link_item) : "") << ',' << csvField(it.link_uri) << ','
        << csvField(it.author) << ',' << isoTime(it.created_us) << ',' << isoTime(it.modified_us)
        << ',' << it.revision << ',' << places << ',' << (at ? json::number(at->x) : "") << ','
        << (at ? json::number(at->y) : "") << ',' << (at ? json::number(at->z) : "") << "\r\n";
  }
}

namespace {

/// Positions in a projected CRS to longitude, latitude (degrees on WGS 84) and height, by PROJ.
class ToWgs84 {
 public:
  explicit ToWgs84(const std::string& crs) : mContext(proj_context_create()) {
    PJ* raw = proj_create_crs_to_crs(mContext, crs.c_str(), "EPSG:4326", nullptr);
    if (raw) {
      mTransform = proj_normalize_for_visualization(mContext, raw);  // longitude first
      proj_destroy(raw);
    }
    if (!mTransform) {
      const std::string why = proj_context_errno_string(mContext, proj_context_errno(mContext));
      proj_context_destroy(mContext);
      throw AnnotationError(AnnotationError::Kind::kBadInput,
                            "exportGeoJson(): " + crs +
                                ": not a coordinate reference system PROJ knows (" + why + ")");
    }
  }
  ~ToWgs84() {
    proj_destroy(mTransform);
    proj_context_destroy(mContext);
  }
  ToWgs84(const ToWgs84&) = delete;
  ToWgs84& operator=(const ToWgs84&) = delete;

  glm::dvec3 operator()(const glm::dvec3& p) const {
    const PJ_COORD c = proj_trans(mTransform, PJ_FWD, proj_coord(p.x, p.y, p.z, 0.0));
    if (!std::isfinite(c.xyz.x) || !std::isfinite(c.xyz.y))
      throw AnnotationError(AnnotationError::Kind::kBadInput,
                            "exportGeoJson(): a position (" + json::number(p.x) + ", " +
                                json::number(p.y) + ") lies outside its CRS's area");
    return {c.xyz.x, c.xyz.y, p.z};
  }

 private:
  PJ_CONTEXT* mContext;
  PJ* mTransform = nullptr;
};

}  // namespace

void exportGeoJson(AnnotationDb& db, std::ostream& out, const std::optional<Georeference>& geo_in) {
  std::optional<Georeference> geo = geo_in;
  if (!geo)
    if (const auto stored = db.georeference()) geo = Georeference{stored->first, stored->second};
  if (!geo)
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          "exportGeoJson(): " + db.file().string() +
                              " is not georeferenced: its positions are a local frame; give a "
                              "projected CRS and the local origin's coordinates in it");
  std::string upper = geo->crs;
  std::transform(upper.begin(), upper.end(), upper.begin(), ::toupper);
  for (const char* geographic : {"EPSG:4326", "EPSG:4979", "EPSG:4258", "OGC:CRS84", "CRS84"})
    if (upper == geographic)
      throw AnnotationError(AnnotationError::Kind::kBadInput,
                            "exportGeoJson(): " + geo->crs +
                                " is geographic (degrees); the store's positions are metres and "
                                "need a projected CRS (UTM, a national grid)");
  // RFC 7946: longitude and latitude on WGS 84 (degrees), then the height; no "crs" member. The
  // projected coordinates stay in each feature's properties, with the CRS they are in.
  const ToWgs84 wgs84(geo->crs);
  std::string s = "{\"type\": \"FeatureCollection\",\n\"features\": [";
  bool first = true;
  for (const Place& p : db.places()) {
    if (p.kind == PlaceKind::kSelection) continue;
    std::string items;
    for (int64_t id : db.itemsAt(p.id))
      if (const auto it = db.item(id)) items += (items.empty() ? "" : ", ") + itemJson(*it);
    const glm::dvec3 projected = geo->origin + p.position;
    s += (first ? "\n" : ",\n") + std::string("{\"type\": \"Feature\", \"id\": ") +
         std::to_string(p.id) +
         ", \"geometry\": {\"type\": \"Point\", \"coordinates\": " + vec(wgs84(projected)) +
         "}, \"properties\": {\"kind\": " + jsonString(toString(p.kind)) +
         ", \"model\": " + jsonString(p.model) + ", \"crs\": " + jsonString(geo->crs) +
         ", \"projected\": " + vec(projected) + ", \"local_position\": " + vec(p.position);
    if (p.kind == PlaceKind::kHotSpot) s += ", \"radius\": " + json::number(p.radius);
    if (p.view) s += ", \"view\": " + viewJson(*p.view, geo->origin);
    s += ", \"items\": [" + items + "]}}";
    first = false;
  }
  s += "\n]}\n";
  out << s;
}

ImportCounts importJson(AnnotationDb& db, std::string_view bytes, const std::string& name) {
  Value doc;
  try {
    doc = json::parse(bytes);
  } catch (const json::ParseError& e) {
    throw AnnotationError(AnnotationError::Kind::kBadInput,
                          "importJson(): " + name + ": not JSON: " + e.what());
  }
  Fields top(doc, "$", name);
  if (top.string("format") != kFormat)
    top.fail("$.format", std::string("expected \"") + kFormat + "\"");
  if (const int64_t version = top.integer("version"); version != kFormatVersion)
    top.fail("$.version", "this build reads version " + std::to_string(kFormatVersion) +
                              ", the file is version " + std::to_string(version));

  // Parse and check everything before the first write.
  std::optional<Georeference> geo;
  const Value* g = top.optional("georeference");
  if (g && g->type != Value::Type::kNull) {
    Fields f(*g, "$.georeference", name);
    geo = Georeference{f.string("crs"), f.vec3("origin")};
    f.done();
  }
  std::vector<Layer> layers;
  const Value& layer_array = arrayField(top, "layers");
  for (size_t i = 0; i < layer_array.array.size(); ++i) {
    Fields f(layer_array.array[i], "$.layers[" + std::to_string(i) + "]", name);
    layers.push_back({f.string("path"), f.boolean("visible")});
    f.done();
  }
  std::vector<Item> items;
  std::map<int64_t, size_t> item_index;
  const Value& item_array = arrayField(top, "items");
  for (size_t i = 0; i < item_array.array.size(); ++i) {
    const std::string path = "$.items[" + std::to_string(i) + "]";
    Fields f(item_array.array[i], path, name);
    Item it;
    it.id = f.integer("id");
    if (it.id < 1) f.fail(f.at("id"), "must be >= 1");
    if (!item_index.emplace(it.id, i).second)
      f.fail(f.at("id"), "item " + std::to_string(it.id) + " appears twice");
    it.layer = f.string("layer");
    const auto kind = parseItemKind(f.string("kind"));
    if (!kind) f.fail(f.at("kind"), "expected text, number, image or link");
    it.kind = *kind;
    it.title = f.string("title");
    it.text = f.string("text");
    if (it.kind == ItemKind::kNumber) {
      it.number = f.real("number");
      it.unit = f.string("unit");
    } else if (it.kind == ItemKind::kImage) {
      it.mime = f.string("mime");
      if (f.optional("data"))
        it.data = f.base64("data");
      else
        it.path = f.string("path");
    } else if (it.kind == ItemKind::kLink) {
      if (f.optional("link_item"))
        it.link_item = f.integer("link_item");
      else
        it.link_uri = f.string("link_uri");
    }
    it.author = f.string("author");
    it.created_us = f.integer("created_us");
    it.modified_us = f.integer("modified_us");
    it.revision = f.integer("revision");
    f.done();
    items.push_back(std::move(it));
  }
  for (size_t i = 0; i < items.size(); ++i) {
    if (items[i].link_item == items[i].id)
      top.fail("$.items[" + std::to_string(i) + "].link_item", "an item cannot link to itself");
    if (items[i].link_item && !item_index.count(items[i].link_item))
      top.fail("$.items[" + std::to_string(i) + "].link_item",
               "links to item " + std::to_string(items[i].link_item) + ", not in the file");
  }
  std::vector<Place> places;
  std::set<int64_t> place_ids;
  const Value& place_array = arrayField(top, "places");
  for (size_t i = 0; i < place_array.array.size(); ++i) {
    Fields f(place_array.array[i], "$.places[" + std::to_string(i) + "]", name);
    Place p;
    p.id = f.integer("id");
    if (p.id < 1) f.fail(f.at("id"), "must be >= 1");
    if (!place_ids.insert(p.id).second)
      f.fail(f.at("id"), "place " + std::to_string(p.id) + " appears twice");
    const auto kind = parsePlaceKind(f.string("kind"));
    if (!kind) f.fail(f.at("kind"), "expected selection, point or hotspot");
    p.kind = *kind;
    p.model = f.string("model");
    p.position = f.vec3("position");
    if (p.kind == PlaceKind::kHotSpot) p.radius = f.real("radius");
    if (const Value* v = f.optional("view")) {
      Fields fv(*v, f.at("view"), name);
      p.view = StoredView{fv.vec3("eye"), fv.vec3("target"), fv.vec3("up"), fv.real("fovy_deg")};
      fv.done();
    }
    if (p.kind == PlaceKind::kSelection) {
      p.selection_id = f.string("selection_id");
      p.selection = f.base64("selection");
    }
    f.done();
    places.push_back(std::move(p));
  }
  std::vector<std::pair<int64_t, int64_t>> links;
  const Value& attachment_array = arrayField(top, "attachments");
  for (size_t i = 0; i < attachment_array.array.size(); ++i) {
    const std::string path = "$.attachments[" + std::to_string(i) + "]";
    const Value& a = attachment_array.array[i];
    if (a.type != Value::Type::kArray || a.array.size() != 2)
      top.fail(path, "expected [item, place]");
    const int64_t item = top.toInteger(a.array[0], path + "[0]");
    const int64_t place = top.toInteger(a.array[1], path + "[1]");
    if (!item_index.count(item)) top.fail(path + "[0]", "no item " + std::to_string(item));
    if (!place_ids.count(place)) top.fail(path + "[1]", "no place " + std::to_string(place));
    links.emplace_back(item, place);
  }
  top.done();

  ImportCounts counts;
  db.transaction([&] {
    // Links between imported items may point forwards (or in a cycle); their foreign keys are
    // checked at the commit instead of at each insert.
    if (sqlite3_exec(db.handle(), "PRAGMA defer_foreign_keys = ON", nullptr, nullptr, nullptr) !=
        SQLITE_OK)
      throw AnnotationError(AnnotationError::Kind::kIo,
                            "importJson(): " + name + ": cannot defer foreign keys");
    const bool keep = db.items().empty() && db.places().empty();
    std::map<int64_t, int64_t> item_ids, place_ids_new;
    int64_t next_item = nextId(db, "items"), next_place = nextId(db, "places");
    for (const Item& it : items) item_ids[it.id] = keep ? it.id : next_item++;
    for (const Place& p : places) place_ids_new[p.id] = keep ? p.id : next_place++;
    if (geo) db.setGeoreference(geo->crs, geo->origin);
    for (size_t i = 0; i < layers.size(); ++i) {
      withPath(name, "$.layers[" + std::to_string(i) + "]", [&] {
        db.addLayer(layers[i].path);
        db.setLayerVisible(layers[i].path, layers[i].visible);
      });
      ++counts.layers;
    }
    for (size_t i = 0; i < items.size(); ++i) {
      Item it = items[i];
      it.id = item_ids.at(it.id);
      if (it.link_item) it.link_item = item_ids.at(it.link_item);
      withPath(name, "$.items[" + std::to_string(i) + "]",
               [&] { return db.importItem(it, true, true); });
      ++counts.items;
    }
    for (size_t i = 0; i < places.size(); ++i) {
      Place p = places[i];
      p.id = place_ids_new.at(p.id);
      withPath(name, "$.places[" + std::to_string(i) + "]",
               [&] { return db.importPlace(p, true); });
      ++counts.places;
    }
    for (const auto& [item, place] : links) {
      db.attach(item_ids.at(item), place_ids_new.at(place));
      ++counts.attachments;
    }
  });
  return counts;
}

}  // namespace tessera::annotate
