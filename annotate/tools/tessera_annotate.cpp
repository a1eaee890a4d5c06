// tessera-annotate: the annotation database from the command line: list, search,
// add, export (CSV, JSON, GeoJSON), import, layers, georef. `tessera-annotate --help` lists
// them. Exit codes (README, "Exit codes"): 0 success, 1 bad input (a damaged or newer database,
// a malformed import, a bad query), 2 bad command line, 3 an output could not be written.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>

#include <tessera/annotate/annotation_db.h>
#include <tessera/annotate/annotation_io.h>
#include <tessera/core/cli.h>
#include <tessera/core/file_checks.h>
#include <tessera/sync/view.h>

namespace {

using namespace tessera::annotate;
namespace cli = tessera::cli;
namespace fs = std::filesystem;

constexpr size_t kMaxImportBytes = size_t(1) << 30;

std::string defaultAuthor() {
  const char* user = std::getenv("USER");
  return user && *user ? user : "tessera-annotate";
}

/// A number as written, the shortest text that reads back to the same double (list, show and
/// place all print numbers so).
std::string number(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string vec3(const glm::dvec3& v) {
  return number(v.x) + "," + number(v.y) + "," + number(v.z);
}

/// What a selection place holds, in words: a measurement (anchored at its first point) or a
/// selected region, its size.
std::string selectionWords(const Place& p) {
  if (p.selection_id == kMeasurementBlob)
    return "(a measurement at " + vec3(p.position) + ", " + std::to_string(p.selection.size()) +
           " bytes)";
  if (p.selection_id == kSelectionBlob)
    return "(a selected region, " + std::to_string(p.selection.size()) + " bytes)";
  return "(" + p.selection_id + ", " + std::to_string(p.selection.size()) + " bytes)";
}

void printItem(AnnotationDb& db, const Item& it) {
  std::cout << it.id << "\t" << it.layer << (db.layerShown(it.layer) ? "" : " (hidden)") << "\t"
            << toString(it.kind) << "\t" << it.title;
  switch (it.kind) {
    case ItemKind::kText:
      break;
    case ItemKind::kNumber:
      std::cout << " = " << number(it.number) << (it.unit.empty() ? "" : " ") << it.unit;
      break;
    case ItemKind::kImage:
      std::cout << " [" << it.mime << ", "
                << (it.path.empty() ? std::to_string(it.data.size()) + " bytes" : it.path) << "]";
      break;
    case ItemKind::kLink:
      std::cout << " -> " << (it.link_item ? "item " + std::to_string(it.link_item) : it.link_uri);
      break;
  }
  std::cout << "\tr" << it.revision << " by " << it.author;
  for (int64_t place : db.placesOf(it.id)) {
    const auto p = db.place(place);
    if (!p) continue;
    std::cout << "\t" << toString(p->kind) << " " << place << " on " << p->model;
    if (p->kind != PlaceKind::kSelection) std::cout << " at " << vec3(p->position);
    if (p->kind == PlaceKind::kSelection) std::cout << " " << selectionWords(*p);
  }
  std::cout << "\n";
}

void printPlace(const Place& p) {
  const auto v3 = vec3;
  std::cout << "place " << p.id << "\t" << toString(p.kind) << " on " << p.model;
  if (p.kind != PlaceKind::kSelection) std::cout << " at " << v3(p.position);
  if (p.kind == PlaceKind::kHotSpot) std::cout << " radius " << number(p.radius);
  if (p.kind == PlaceKind::kSelection) std::cout << " " << selectionWords(p);
  if (p.view)
    std::cout << "\tview eye " << v3(p.view->eye) << " target " << v3(p.view->target) << " up "
              << v3(p.view->up) << " fovy " << number(p.view->fovy_deg);
  std::cout << "\n";
}

/// Writes `text` to `path` through a temporary file renamed into place, so a failed export
/// never leaves half a file. Returns an error message, or "".
std::string writeFile(const fs::path& path, const std::string& text) {
  const fs::path tmp = path.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return "cannot write " + path.string() + ": " + tessera::whyNotWritable(tmp, errno);
    out << text;
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      return "writing " + path.string() + " failed (disk full?)";
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return "cannot write " + path.string() + ": " + ec.message();
  }
  return {};
}

int run(int argc, char** argv) {
  CLI::App app{"tessera-annotate: the annotation database beside a scene (items, layers, places)"};
  app.require_subcommand(1);
  std::string db_file, author = defaultAuthor();
  app.add_option("-d,--db", db_file, "The annotation database (add, import, georef create it)")
      ->required();
  app.add_option("--author", author, "Who makes the edits (site or user name)")
      ->capture_default_str();

  std::string layer;
  auto* list = app.add_subcommand("list", "List items (all, or a layer and its sublayers)");
  list->add_option("--layer", layer, "Only this layer and its sublayers (\"a/b\")");

  std::string query;
  int limit = 20;
  auto* search = app.add_subcommand(
      "search", "Full-text search (FTS5: words, \"phrases\", prefix*, AND/OR/NOT, title:word)");
  search->add_option("QUERY", query, "The query")->required();
  search->add_option("--limit", limit, "At most this many hits")
      ->check(cli::integerRange(1, 10000))
      ->capture_default_str();

  Item item;
  std::string kind = "text", at, model = "model", image_file;
  double number = 0.0;
  int64_t count = 1;
  auto* add = app.add_subcommand("add", "Add an item, optionally at a point of a model");
  add->add_option("--layer", item.layer, "Its layer (\"a/b/c\"; created if absent)")->required();
  add->add_option("--title", item.title,
                  "Its label, at most " + std::to_string(kMaxTitleBytes) + " bytes of UTF-8")
      ->required();
  add->add_option("--kind", kind, "text, number, image or link")
      ->check(CLI::IsMember({"text", "number", "image", "link"}))
      ->capture_default_str();
  add->add_option("--text", item.text,
                  "The text (or a caption for other kinds), at most " +
                      std::to_string(kMaxTextBytes >> 20) + " MiB of UTF-8");
  std::string text_file;
  add->add_option("--text-file", text_file,
                  "The text from this file (- for standard input), for texts longer than a "
                  "command line")
      ->excludes("--text");
  auto* number_option = add->add_option("--number", number, "kind number: the value (required)")
                            ->check(cli::finiteRange(-1e300, 1e300));
  add->add_option("--unit", item.unit, "kind number: its unit (m, m^2, deg...)");
  add->add_option("--image", item.path, "kind image: the image file's path (stored as a path)");
  add->add_option("--embed", image_file,
                  "kind image: a file whose bytes are stored in the item, at most " +
                      std::to_string(kMaxBlobBytes >> 20) + " MiB");
  add->add_option("--mime", item.mime, "kind image: its MIME type (image/png...)");
  add->add_option("--link-item", item.link_item, "kind link: the item linked to")
      ->check(cli::integerRange<int64_t>(1, INT64_MAX));
  add->add_option("--link-uri", item.link_uri, "kind link: a document URI (https:..., file:...)");
  add->add_option("--at", at, "Attach at this point X,Y,Z (world metres)");
  add->add_option("--model", model, "With --at: the model the point is on")->capture_default_str();
  double radius = 0.0, fovy = 45.0;
  std::string eye, target, up = "0,0,1";
  int64_t place_id = 0;
  add->add_option("--radius", radius, "With --at: make it a hot spot of this radius (metres)")
      ->check(cli::positiveFinite(kMaxCoordinate));
  add->add_option("--eye", eye, "With --at: the stored view's eye X,Y,Z (needed by hot spots)");
  add->add_option("--target", target, "The stored view's target X,Y,Z (default: --at)");
  add->add_option("--up", up, "The stored view's up X,Y,Z")->capture_default_str();
  add->add_option("--fovy", fovy, "The stored view's vertical field of view (degrees)")
      ->check(cli::finiteRange(1.0, 179.0))
      ->capture_default_str();
  add->add_option("--place", place_id, "Attach to this existing place instead of --at")
      ->check(cli::integerRange<int64_t>(1, INT64_MAX))
      ->excludes("--at");
  add->add_option("--count", count,
                  "Add this many copies (titles get \" #k\"), each printed once committed")
      ->check(cli::integerRange<int64_t>(1, 10000000))
      ->capture_default_str();

  int64_t show_id = 0;
  auto* show_item = app.add_subcommand(
      "show", "An item, the places it hangs at with their stored views, the items linking to it");
  show_item->add_option("ITEM", show_id, "The item's id")->required();
  int64_t at_id = 0;
  auto* show_place =
      app.add_subcommand("place", "A place (point, hot spot, selection) and the items it opens");
  show_place->add_option("PLACE", at_id, "The place's id")->required();

  std::string format, output, crs, origin;
  auto* exp = app.add_subcommand("export", "Write the database as CSV, JSON or GeoJSON");
  exp->add_option("--format", format, "csv, json or geojson")
      ->required()
      ->check(CLI::IsMember({"csv", "json", "geojson"}));
  exp->add_option("-o,--output", output, "The file to write")->required();
  exp->add_option("--layer", layer, "csv: only this layer and its sublayers");
  exp->add_option("--crs", crs, "geojson: the projected CRS (EPSG:32633...); else the stored one");
  exp->add_option("--origin", origin, "geojson: the local origin's X,Y,Z in that CRS");

  std::string input;
  auto* imp = app.add_subcommand("import", "Import a JSON export (all of it or nothing)");
  imp->add_option("FILE", input, "The .json file")->required();

  std::vector<std::string> show, hide;
  auto* lay = app.add_subcommand("layers", "List layers; show or hide some first");
  lay->add_option("--show", show, "Make these layers visible");
  lay->add_option("--hide", hide, "Hide these layers (their sublayers with them)");

  auto* check = app.add_subcommand(
      "check",
      "Check every page and index of the database (PRAGMA integrity_check); every "
      "other command checks the pages' structure first (quick_check)");

  auto* georef = app.add_subcommand("georef", "Store the CRS and origin of the local frame");
  georef->add_option("--crs", crs, "The projected CRS (EPSG:32633...)")->required();
  georef->add_option("--origin", origin, "The local origin's X,Y,Z in that CRS")->required();

  if (const auto code = cli::parse(app, argc, argv, "tessera-annotate")) return *code;

  // Every composite value is checked before anything is opened, so a bad one is named as such
  // (exit 2), not hidden behind a database that cannot be opened.
  std::optional<Place> place;
  if (add->parsed()) {
    if (!at.empty()) {
      place = Place{};
      place->kind = radius > 0.0 ? PlaceKind::kHotSpot : PlaceKind::kPoint;
      place->model = model;
      place->position = cli::parseVec3(at, "--at");
      place->radius = radius;
      const glm::dvec3 up_v = cli::parseVec3(up, "--up");
      const glm::dvec3 target_v =
          target.empty() ? place->position : cli::parseVec3(target, "--target");
      if (!eye.empty()) {
        StoredView v{cli::parseVec3(eye, "--eye"), target_v, up_v, fovy};
        tessera::sync::requireView(v.eye, v.target, v.up, "--eye/--target/--up");
        place->view = v;
      } else if (radius > 0.0) {
        throw cli::UsageError("--radius: a hot spot needs a stored view (--eye)");
      }
    } else if (radius > 0.0 || !eye.empty() || !target.empty()) {
      throw cli::UsageError("--radius, --eye, --target: only with --at");
    }
  }
  if (add->parsed() && kind == "number" && number_option->count() == 0)
    throw cli::UsageError("--kind number needs --number");
  if (add->parsed() && kind != "number" && number_option->count() > 0)
    throw cli::UsageError("--number: only with --kind number");
  std::optional<glm::dvec3> origin_v;
  if (!origin.empty()) origin_v = cli::parseVec3(origin, "--origin");

  // Only edits create a database: a mistyped path to list or export is an error, not an empty
  // new file. Reads open it read-only, so they work where nothing can be written (a read-only
  // folder or medium) and never change it.
  const bool reads = list->parsed() || search->parsed() || exp->parsed() || show_item->parsed() ||
                     show_place->parsed() || check->parsed() ||
                     (lay->parsed() && show.empty() && hide.empty());
  if (reads) {
    std::error_code ec;
    const bool exists = fs::exists(db_file, ec);
    if (!exists || (fs::is_regular_file(db_file, ec) && fs::file_size(db_file, ec) == 0))
      throw AnnotationError(AnnotationError::Kind::kCannotOpen,
                            "AnnotationDb: " + db_file +
                                (exists ? ": is empty" : ": does not exist") +
                                " (add, import and georef create a database)");
  }
  AnnotationDbOptions options;
  options.read_only = reads;
  options.check = check->parsed() ? DbCheck::kFull : DbCheck::kQuick;
  AnnotationDb db = [&] {
    try {
      return AnnotationDb(db_file, options);
    } catch (const AnnotationError& e) {
      // A first-release file must be migrated once, which a read-only open cannot do.
      if (!reads || e.kind() != AnnotationError::Kind::kReadOnly) throw;
      options.read_only = false;
      return AnnotationDb(db_file, options);
    }
  }();

  if (list->parsed()) {
    for (const Item& it : db.items(layer)) printItem(db, it);
    // Places no item hangs at (a lasso's selection): listed too, as what they are.
    if (layer.empty())
      for (const Place& p : db.places())
        if (db.itemsAt(p.id).empty()) printPlace(p);
  } else if (show_item->parsed()) {
    const auto it = db.item(show_id);
    if (!it)
      throw AnnotationError(AnnotationError::Kind::kNotFound,
                            "AnnotationDb: " + db_file + ": no item " + std::to_string(show_id));
    printItem(db, *it);
    if (!it->text.empty()) std::cout << "text: " << it->text << "\n";
    for (int64_t id : db.placesOf(show_id)) printPlace(*db.place(id));
    for (int64_t id : db.linksTo(show_id)) std::cout << "linked from item " << id << "\n";
  } else if (show_place->parsed()) {
    const auto p = db.place(at_id);
    if (!p)
      throw AnnotationError(AnnotationError::Kind::kNotFound,
                            "AnnotationDb: " + db_file + ": no place " + std::to_string(at_id));
    printPlace(*p);
    for (int64_t id : db.itemsAt(at_id)) printItem(db, *db.item(id));
  } else if (search->parsed()) {
    for (SearchHit hit : db.search(query, limit)) {
      // One line a hit: a text's line breaks and tabs read as spaces.
      std::replace_if(
          hit.snippet.begin(), hit.snippet.end(),
          [](char c) { return c == '\n' || c == '\r' || c == '\t'; }, ' ');
      std::cout << hit.item << "\t" << hit.score << "\t" << hit.snippet << "\n";
    }
  } else if (add->parsed()) {
    item.kind = *parseItemKind(kind);
    if (item.kind == ItemKind::kNumber) item.number = number;
    if (!text_file.empty()) {
      // At most one byte past the limit is read: a longer input is refused, not held.
      auto readBounded = [&](std::istream& in) {
        std::string text(kMaxTextBytes + 1, '\0');
        in.read(text.data(), std::streamsize(text.size()));
        text.resize(size_t(in.gcount()));
        return text;
      };
      if (text_file == "-") {
        item.text = readBounded(std::cin);
      } else {
        if (const auto why = tessera::notRegularFile(text_file))
          throw cli::UsageError("--text-file " + text_file + ": " + *why);
        std::ifstream in(text_file, std::ios::binary);
        item.text = readBounded(in);
      }
      if (item.text.size() > kMaxTextBytes)
        throw cli::UsageError("--text-file " + text_file + ": longer than " +
                              std::to_string(kMaxTextBytes) + " bytes");
    }
    if (!image_file.empty()) {
      if (const auto why = tessera::notRegularFile(image_file))
        throw cli::UsageError("--embed " + image_file + ": " + *why);
      std::ifstream in(image_file, std::ios::binary);
      item.data.assign(std::istreambuf_iterator<char>(in), {});
      if (item.data.size() > kMaxBlobBytes)
        throw cli::UsageError("--embed " + image_file + ": larger than " +
                              std::to_string(kMaxBlobBytes) + " bytes");
    }
    if (place_id && !db.place(place_id))
      throw cli::UsageError("--place " + std::to_string(place_id) + ": no such place");
    const std::string title = item.title;
    for (int64_t k = 1; k <= count; ++k) {
      if (count > 1) item.title = title + " #" + std::to_string(k);
      int64_t id = 0;
      // Item and place commit together: an acknowledged item is whole.
      db.transaction([&] {
        id = db.addItem(item, author);
        if (place) db.attach(id, db.addPlace(*place));
        if (place_id) db.attach(id, place_id);
      });
      // Printed only after the commit returned: every id on stdout is durable.
      std::printf("added %lld\n", static_cast<long long>(id));
      std::fflush(stdout);
    }
  } else if (exp->parsed()) {
    cli::refuseOverwrite(output, std::vector<fs::path>{db_file, db_file + "-wal"}, "-o");
    std::ostringstream text;
    if (format == "csv") {
      exportCsv(db, text, layer);
    } else if (format == "json") {
      exportJson(db, text);
    } else {
      std::optional<Georeference> geo;
      if (crs.empty() != origin.empty())
        throw cli::UsageError("--crs and --origin: give both or neither");
      if (!crs.empty()) geo = Georeference{crs, *origin_v};
      exportGeoJson(db, text, geo);
    }
    if (const std::string error = writeFile(output, text.str()); !error.empty()) {
      std::cerr << "tessera-annotate: " << error << "\n";
      return cli::kExitWriteFailed;
    }
  } else if (imp->parsed()) {
    if (const auto why = tessera::notRegularFile(input))
      throw AnnotationError(AnnotationError::Kind::kBadInput, "import " + input + ": " + *why);
    std::error_code ec;
    if (fs::file_size(input, ec) > kMaxImportBytes)
      throw AnnotationError(AnnotationError::Kind::kBadInput,
                            "import " + input + ": larger than 1 GiB");
    std::ifstream in(input, std::ios::binary);
    const std::string bytes{std::istreambuf_iterator<char>(in), {}};
    const ImportCounts n = importJson(db, bytes, input);
    std::cout << "imported " << n.layers << " layers, " << n.items << " items, " << n.places
              << " places, " << n.attachments << " attachments\n";
  } else if (lay->parsed()) {
    db.transaction([&] {
      for (const std::string& l : show) db.setLayerVisible(l, true);
      for (const std::string& l : hide) db.setLayerVisible(l, false);
    });
    for (const Layer& l : db.layers())
      std::cout << l.path << "\t" << (l.visible ? "visible" : "hidden")
                << (l.visible && !db.layerShown(l.path) ? " (an ancestor is hidden)" : "") << "\n";
  } else if (check->parsed()) {
    std::cout << db_file << ": ok (every page, table and index)\n";
  } else if (georef->parsed()) {
    db.setGeoreference(crs, *origin_v);
  }
  return cli::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runMain("tessera-annotate", [&] { return run(argc, argv); });
}
