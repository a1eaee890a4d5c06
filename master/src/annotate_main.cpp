// tessera-annotate: the annotation database from the command line (issue 16): list, search,
// add, export (CSV, JSON, GeoJSON), import, layers, georef. `tessera-annotate --help` lists
// them. Exit codes (README, "Exit codes"): 0 success, 1 bad input (a damaged or newer database,
// a malformed import, a bad query), 2 bad command line, 3 an output could not be written.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>

#include <tessera/core/cli.h>
#include <tessera/core/file_checks.h>
#include <tessera/master/annotation_db.h>
#include <tessera/master/annotation_io.h>

namespace {

using namespace tessera::master;
namespace cli = tessera::cli;
namespace fs = std::filesystem;

constexpr size_t kMaxImportBytes = size_t(1) << 30;

std::string defaultAuthor() {
  const char* user = std::getenv("USER");
  return user && *user ? user : "tessera-annotate";
}

void printItem(AnnotationDb& db, const Item& it) {
  std::cout << it.id << "\t" << it.layer << (db.layerShown(it.layer) ? "" : " (hidden)") << "\t"
            << toString(it.kind) << "\t" << it.title;
  switch (it.kind) {
    case ItemKind::kText:
      break;
    case ItemKind::kNumber:
      std::cout << " = " << it.number << (it.unit.empty() ? "" : " ") << it.unit;
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
    if (p->kind != PlaceKind::kSelection)
      std::cout << " at " << p->position.x << "," << p->position.y << "," << p->position.z;
  }
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
  app.add_option("-d,--db", db_file, "The annotation database (created if absent)")->required();
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
  add->add_option("--title", item.title, "Its label")->required();
  add->add_option("--kind", kind, "text, number, image or link")
      ->check(CLI::IsMember({"text", "number", "image", "link"}))
      ->capture_default_str();
  add->add_option("--text", item.text, "The text (or a caption for other kinds)");
  add->add_option("--number", number, "kind number: the value")
      ->check(cli::finiteRange(-1e300, 1e300));
  add->add_option("--unit", item.unit, "kind number: its unit (m, m^2, deg...)");
  add->add_option("--image", item.path, "kind image: the image file's path (stored as a path)");
  add->add_option("--embed", image_file, "kind image: a file whose bytes are stored in the item");
  add->add_option("--mime", item.mime, "kind image: its MIME type (image/png...)");
  add->add_option("--link-item", item.link_item, "kind link: the item linked to")
      ->check(cli::integerRange<int64_t>(1, INT64_MAX));
  add->add_option("--link-uri", item.link_uri, "kind link: a document URI (https:..., file:...)");
  add->add_option("--at", at, "Attach at this point X,Y,Z (world metres)");
  add->add_option("--model", model, "With --at: the model the point is on")->capture_default_str();
  add->add_option("--count", count,
                  "Add this many copies (titles get \" #k\"), each printed once committed")
      ->check(cli::integerRange<int64_t>(1, 10000000))
      ->capture_default_str();

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

  auto* georef = app.add_subcommand("georef", "Store the CRS and origin of the local frame");
  georef->add_option("--crs", crs, "The projected CRS (EPSG:32633...)")->required();
  georef->add_option("--origin", origin, "The local origin's X,Y,Z in that CRS")->required();

  if (const auto code = cli::parse(app, argc, argv, "tessera-annotate")) return *code;

  AnnotationDb db(db_file);

  if (list->parsed()) {
    for (const Item& it : db.items(layer)) printItem(db, it);
  } else if (search->parsed()) {
    for (const SearchHit& hit : db.search(query, limit))
      std::cout << hit.item << "\t" << hit.score << "\t" << hit.snippet << "\n";
  } else if (add->parsed()) {
    item.kind = *parseItemKind(kind);
    if (item.kind == ItemKind::kNumber) item.number = number;
    if (!image_file.empty()) {
      if (const auto why = tessera::notRegularFile(image_file))
        throw cli::UsageError("--embed " + image_file + ": " + *why);
      std::ifstream in(image_file, std::ios::binary);
      item.data.assign(std::istreambuf_iterator<char>(in), {});
      if (item.data.size() > kMaxBlobBytes)
        throw cli::UsageError("--embed " + image_file + ": larger than " +
                              std::to_string(kMaxBlobBytes) + " bytes");
    }
    std::optional<glm::dvec3> point;
    if (!at.empty()) point = cli::parseVec3(at, "--at");
    const std::string title = item.title;
    for (int64_t k = 1; k <= count; ++k) {
      if (count > 1) item.title = title + " #" + std::to_string(k);
      int64_t id = 0;
      // Item and place commit together: an acknowledged item is whole.
      db.transaction([&] {
        id = db.addItem(item, author);
        if (point) {
          Place p;
          p.kind = PlaceKind::kPoint;
          p.model = model;
          p.position = *point;
          db.attach(id, db.addPlace(p));
        }
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
      if (!crs.empty()) geo = Georeference{crs, cli::parseVec3(origin, "--origin")};
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
  } else if (georef->parsed()) {
    db.setGeoreference(crs, cli::parseVec3(origin, "--origin"));
  }
  return cli::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  return cli::runMain("tessera-annotate", [&] { return run(argc, argv); });
}
