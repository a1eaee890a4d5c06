// The annotation database: what people learn about a model, kept in an SQLite file beside the
// scene ("Annotation", "Information").
//
// The information model follows the thesis (patch-lod-annotation-thesis.txt, ch. 5: text,
// numbers, images and links assigned to selected regions, kept in a database next to the model)
// and Bettio et al. (point-based-local-remote-exploration.txt, sec. 3.4: hot spots, a
// hierarchical tree of information layers switched on and off, links both ways between the
// model and its documents, a view stored with the place):
//
//  - a Layer is a path "a/b/c"; every prefix is a layer too and is created with it. An item is
//    shown when its layer and every ancestor are visible.
//  - an Item is one piece of information: text, a number with its unit, an image (a file path
//    or the bytes themselves, with a MIME type) or a link (to another item, or to a document
//    URI). Every item records its author, created/modified times and a revision.
//  - a Place is where on the model information hangs: a selection (an opaque blob the
//    selection code fills, per-chunk ranges), a point, or a hot spot (point + radius + view).
//    Positions are world coordinates in metres, double precision.
//  - an attachment joins an item and a place (many to many: a hot spot opens several items, an
//    item may hang at several places). Both directions are queries: itemsAt(place) goes from the
//    model to the information, placesOf(item) from the information back to the model with the
//    stored view to fly to. Links between items are likewise read both ways (linksTo()).
//
// Durability: every edit is one transaction committed with synchronous=FULL in WAL mode; a call
// returns only after the commit (and the fsync of the log), so an acknowledged edit survives
// kill -9 of the process (tests/master/annotation_db_test.cpp kills a writer mid-stream) and a
// power cut as far as the disk honours fsync (not tested). Cost: one fsync per edit, about 4 ms
// on this machine's disk (bench/annotation_db: 227 edits/s; 1653/s in batches of 100 through
// transaction()).
//
// Concurrent edits (two sites editing one item): the master serialises all edits, so they
// reach the database in one order. Each update or removal carries the revision it was based on.
// The rule is optimistic concurrency: an edit whose base revision is the item's current one is
// applied and bumps the revision; an edit based on an older revision is refused with
// AnnotationError::Kind::kConflict (the message names the current revision and its author) and
// changes nothing. Of two sites editing revision r, the first to reach the master wins; the
// second re-reads and decides. Nothing is overwritten silently and the outcome depends only on
// the master's order.
//
// Threading: an AnnotationDb is used by one thread at a time (its SQLite connection is opened
// without a mutex). Several connections and processes may open one file (WAL): readers never
// wait, writers wait up to 5 s for each other.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

struct sqlite3;

namespace tessera::annotate {

/// Every failure of the annotation database: the kind says what went wrong, the message
/// starts with the component and names the file ("AnnotationDb: scene.tadb: ... (not an SQLite
/// database, or its header is damaged)").
class AnnotationError : public std::runtime_error {
 public:
  enum class Kind {
    kCannotOpen,    ///< the file or its folder cannot be opened or created
    kNotADatabase,  ///< the file is not an SQLite database (or its header is damaged)
    kCorrupt,       ///< SQLite found the file damaged
    kNewerSchema,   ///< written by a newer Tessera (user_version above kSchemaVersion)
    kReadOnly,      ///< a write to a database opened read-only or on a read-only medium
    kBadInput,      ///< an argument or imported value out of its documented range
    kBadQuery,      ///< a malformed full-text query
    kNotFound,      ///< no item, place or layer with that id or path
    kConflict,      ///< an edit based on a stale revision (see the rule above)
    kIo,            ///< any other SQLite or I/O failure
  };
  AnnotationError(Kind kind, const std::string& what) : std::runtime_error(what), mKind(kind) {}
  Kind kind() const { return mKind; }

 private:
  Kind mKind;
};

/// The schema this build writes. Version 1 was the first release's (one "notes" table, no
/// layers table, no full-text index); version 2's full-text index found words between spaces
/// only. Opening an older file migrates it in one transaction.
constexpr int kSchemaVersion = 3;

/// Bounds on what an item may hold, so a bad site or import cannot fill the disk or the wall.
constexpr size_t kMaxTitleBytes = 1024;
constexpr size_t kMaxTextBytes = 1 << 20;        ///< text body, URIs, paths
constexpr size_t kMaxBlobBytes = 16 << 20;       ///< an embedded image
constexpr size_t kMaxSelectionBytes = 64 << 20;  ///< a selection's per-chunk ranges
constexpr size_t kMaxLayerPathBytes = 256;       ///< "a/b/c", at most 16 levels
constexpr size_t kMaxNameBytes = 256;            ///< authors, models, units, MIME types
constexpr double kMaxCoordinate = 1e12;          ///< metres, |x|, |y|, |z|

enum class ItemKind { kText, kNumber, kImage, kLink };
enum class PlaceKind { kSelection, kPoint, kHotSpot };

const char* toString(ItemKind kind);
const char* toString(PlaceKind kind);
std::optional<ItemKind> parseItemKind(const std::string& text);
std::optional<PlaceKind> parsePlaceKind(const std::string& text);

/// A camera to fly to: world metres, fovy in degrees (0, 180).
struct StoredView {
  glm::dvec3 eye{0.0};
  glm::dvec3 target{0.0, 0.0, -1.0};
  glm::dvec3 up{0.0, 1.0, 0.0};
  double fovy_deg = 45.0;
  bool operator==(const StoredView&) const = default;
};

struct Layer {
  std::string path;     ///< "a/b/c": segments of printable text without '/', none empty
  bool visible = true;  ///< its own flag; layerShown() also looks at the ancestors
  bool operator==(const Layer&) const = default;
};

struct Item {
  int64_t id = 0;  ///< assigned by addItem()
  std::string layer;
  ItemKind kind = ItemKind::kText;
  std::string title;          ///< a label, at most kMaxTitleBytes
  std::string text;           ///< the text (kText) or a caption (other kinds)
  double number = 0.0;        ///< kNumber: finite
  std::string unit;           ///< kNumber: "m", "m^2", "deg", may be empty
  std::string mime;           ///< kImage: "image/png"...
  std::string path;           ///< kImage: a file path, or empty when `data` holds the image
  std::vector<uint8_t> data;  ///< kImage: the bytes, or empty when `path` names the file
  int64_t link_item = 0;      ///< kLink: the item linked to, or 0 when `link_uri` is set
  std::string link_uri;       ///< kLink: a document ("https://...", "file:///...")
  // Set by the database; the values passed to addItem()/updateItem() are ignored.
  std::string author;
  int64_t created_us = 0;  ///< microseconds since the Unix epoch, UTC
  int64_t modified_us = 0;
  int64_t revision = 0;  ///< 1 when added, +1 per applied update
  bool operator==(const Item&) const = default;
};

struct Place {
  int64_t id = 0;
  PlaceKind kind = PlaceKind::kPoint;
  std::string model;               ///< the scene's model id
  glm::dvec3 position{0.0};        ///< kPoint, kHotSpot: world metres (-0 reads back as 0)
  double radius = 0.0;             ///< kHotSpot: metres, > 0
  std::optional<StoredView> view;  ///< required for kHotSpot, optional otherwise
  std::string selection_id;        ///< kSelection: the selection code's id
  std::vector<uint8_t> selection;  ///< kSelection: opaque (per-chunk ranges)
  bool operator==(const Place&) const = default;
};

struct SearchHit {
  int64_t item = 0;
  double score = 0.0;   ///< bm25, lower is better (SQLite's sign); hits come best first
  std::string snippet;  ///< the best matching text with matches in [brackets]
};

/// What opening a database checks of its pages before anything is written (AnnotationDbOptions).
enum class DbCheck {
  kQuick,  ///< PRAGMA quick_check: every page's structure (0.3 s at 10^5 items)
  kFull,   ///< PRAGMA integrity_check: also every index against its table
  kNone,   ///< nothing (a database this process has just checked)
};

struct AnnotationDbOptions {
  bool read_only = false;
  /// A damaged file is refused (AnnotationError::Kind::kCorrupt) with its bytes as they were.
  DbCheck check = DbCheck::kQuick;
  /// synchronous=FULL (the default): a commit reaches the disk before the call returns.
  /// NORMAL is only for the benchmark's baseline: in WAL mode a power cut may lose the last
  /// commits (never corrupts).
  bool full_sync = true;
};

class AnnotationDb {
 public:
  /// Opens or creates `file` (created only when it does not exist and !read_only), checks its
  /// pages (AnnotationDbOptions::check) and its schema version (a negative one is refused),
  /// migrates a v1 file, and turns on WAL, foreign keys and the chosen sync.
  /// Throws AnnotationError naming the file: kCannotOpen, kNotADatabase, kCorrupt,
  /// kNewerSchema. ":memory:" opens a private database in memory (no WAL; fuzzing, tests).
  explicit AnnotationDb(const std::filesystem::path& file, AnnotationDbOptions options = {});
  ~AnnotationDb();
  AnnotationDb(AnnotationDb&& other) noexcept;
  AnnotationDb& operator=(AnnotationDb&& other) noexcept;
  AnnotationDb(const AnnotationDb&) = delete;
  AnnotationDb& operator=(const AnnotationDb&) = delete;

  const std::filesystem::path& file() const { return mFile; }
  int schemaVersion();

  // --- Layers -------------------------------------------------------------------------------
  /// Creates the layer and its ancestors (visible); no-op if it exists. kBadInput on a bad path.
  void addLayer(const std::string& path);
  void setLayerVisible(const std::string& path, bool visible);  ///< kNotFound if absent
  std::vector<Layer> layers();                                  ///< all, sorted by path
  /// Whether items of `path` are shown: it and every ancestor visible.
  bool layerShown(const std::string& path);

  // --- Items (each call one committed transaction) ------------------------------------------
  /// Validates, creates the item's layer if needed, stores it with revision 1 and `author`;
  /// returns its id after the commit.
  int64_t addItem(const Item& item, const std::string& author);
  /// Replaces the item's content (everything but id, author, created time) if `base_revision`
  /// is its current revision; returns the new revision. kNotFound, kConflict.
  int64_t updateItem(const Item& item, int64_t base_revision, const std::string& author);
  /// kNotFound, kConflict as updateItem(). Its attachments go with it. Refused (kBadInput)
  /// while link items point at it: remove or re-point them first.
  void removeItem(int64_t id, int64_t base_revision);
  std::optional<Item> item(int64_t id);
  /// Items of `layer` and its sublayers ("" for all), by id.
  std::vector<Item> items(const std::string& layer = "");
  /// Items whose kLink points at `id` (the link read backwards).
  std::vector<int64_t> linksTo(int64_t id);
  /// Stores `item` as it is, author, times and revision included (import, migration); the
  /// same checks as addItem() and: author not empty, revision >= 1, created <= modified.
  /// `keep_id`: insert under item.id (fails with kBadInput if taken), else a new id.
  /// `link_later`: a kLink's target item may arrive later in the same transaction (import of
  /// items linking forwards); the caller turns on PRAGMA defer_foreign_keys so the commit
  /// checks it.
  int64_t importItem(const Item& item, bool keep_id, bool link_later = false);

  // --- Places and attachments ---------------------------------------------------------------
  /// Validates (finite positions within kMaxCoordinate: NaN and inf are refused; a hot spot
  /// has a radius > 0 and a view) and stores the place; returns its id.
  int64_t addPlace(const Place& place);
  int64_t importPlace(const Place& place, bool keep_id);  ///< as importItem()
  std::optional<Place> place(int64_t id);
  std::vector<Place> places();
  void attach(int64_t item, int64_t place);  ///< kNotFound if either is absent; idempotent
  void detach(int64_t item, int64_t place);
  /// Removes the place and its attachments (its items stay). kNotFound if absent.
  void removePlace(int64_t place);
  std::vector<int64_t> itemsAt(int64_t place);  ///< model -> information
  std::vector<int64_t> placesOf(int64_t item);  ///< information -> model (and its view)
  /// Points and hot spots of `model` within `radius` metres of `centre` (Bettio et al.'s focus
  /// circle: only the hot spots near the cursor), nearest first. Cost: the places of `model`
  /// whose x lies within `radius` of the centre's (an index on model, x).
  std::vector<int64_t> placesNear(const std::string& model, const glm::dvec3& centre,
                                  double radius);

  // --- Full-text search ---------------------------------------------------------------------
  /// FTS5 query over title, text and layer (bm25, title weighted 10, layer 2, text 1): words,
  /// "phrases", prefix*, AND/OR/NOT, column filters (title: crack). At most `limit` hits, best
  /// first. A malformed query throws kBadQuery with SQLite's reason. Cost: every matching item
  /// is scored, so it grows with the matches: ~0.5 ms for a rare word, ~150 ms for a word in
  /// half of 10^5 items on this machine (bench/annotation_db).
  std::vector<SearchHit> search(const std::string& query, int limit = 50);

  // --- Georeference (for GeoJSON) -----------------------------------------------------------
  /// The store's positions are a local frame; `crs` (e.g. "EPSG:32633") and `origin` (that
  /// CRS's coordinates of the local origin) say where it sits. Unset: not georeferenced.
  void setGeoreference(const std::string& crs, const glm::dvec3& origin);
  std::optional<std::pair<std::string, glm::dvec3>> georeference();

  // --- Batches and checks -------------------------------------------------------------------
  /// Runs `body` in one transaction (the edits inside commit together, or not at all when it
  /// throws). Nested calls join the outer transaction.
  template <typename F>
  void transaction(F&& body) {
    begin();
    try {
      body();
    } catch (...) {
      rollback();
      throw;
    }
    commit();
  }
  /// PRAGMA integrity_check: "ok" or SQLite's list of problems.
  std::string integrityCheck();
  /// SQLite's PRAGMA data_version: changes when another connection (tessera-annotate, a second
  /// tool) committed to the file since the last call, not for this connection's own commits.
  int64_t dataVersion();

  /// The raw connection, for the exporter and the tests.
  sqlite3* handle() { return mDb; }

 private:
  void begin();
  void commit();
  void rollback();
  void exec(const char* sql);
  [[noreturn]] void fail(int rc, const std::string& what);
  void migrate(int from);
  void ensureLayer(const std::string& path);
  void checkItem(const Item& item, bool check_link_target = true);
  void checkPlace(const Place& place);

  std::filesystem::path mFile;
  sqlite3* mDb = nullptr;
  int mDepth = 0;  ///< open transaction() nesting
};

/// How a selection place's bytes are to be read (Place::selection_id): the scene payload the
/// node carried, serialized (a measurement, or a lasso's or snap's selection; annotation_scene.h).
constexpr const char* kMeasurementBlob = "scene.MeasurementPayload";
constexpr const char* kSelectionBlob = "scene.SelectionPayload";

/// The v1 and v2 schemas, as the releases that wrote them created them (kept so tests can write
/// such files).
extern const char* const kSchemaV1Sql;
extern const char* const kSchemaV2Sql;

}  // namespace tessera::annotate
