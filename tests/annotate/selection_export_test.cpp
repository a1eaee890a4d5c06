// `tessera-lod export --selection DB:ID`: a region selected on a store and stored in a real
// annotation database comes out as exactly the selected points of that store, by the real tool;
// a selection made on another store, a place that is no selection and a bad DB:ID are refused.
#include <gtest/gtest.h>

#include <map>

#include <tessera/annotate/annotation_db.h>
#include <tessera/annotate/selection.h>
#include <tessera/lod/point_reader.h>
#include <tessera/lod/point_store.h>
#include <tessera/lod/store_builder.h>
#include <tessera/scene.pb.h>

#include "../support/command.h"
#include "../support/read_all.h"
#include "../support/temp_dir.h"

namespace tessera::annotate {
namespace {

const std::string kData = TESSERA_DATA_DIR;

test::CommandResult lod(const std::string& args) {
  return test::runCommand(std::string(TESSERA_LOD_TOOL) + " " + args + " 2>&1");
}

/// Stores `s` at a new selection place of `db`; returns the place id.
int64_t storeSelection(const std::filesystem::path& db, const Selection& s) {
  scene::SelectionPayload payload;
  const std::vector<uint8_t> bytes = s.serialize();
  payload.set_elements(std::string(bytes.begin(), bytes.end()));
  payload.set_count(s.count());
  Place p;
  p.kind = PlaceKind::kSelection;
  p.model = "autzen";
  p.selection_id = kSelectionBlob;
  const std::string blob = payload.SerializeAsString();
  p.selection.assign(blob.begin(), blob.end());
  AnnotationDb d(db);
  return d.addPlace(p);
}

TEST(SelectionExport, TheSelectedPointsOfTheStoreComeOutAndNothingElse) {
  test::TempDir dir;
  lod::BuildOptions b;
  b.quiet = true;
  b.leaf_max = 4000;  // several leaves
  lod::buildStore({kData + "/lidar/autzen_trim.las"}, dir / "a.tlod", b);
  auto store = lod::PointStore::open(dir / "a.tlod");
  // Every other leaf: the first half of its points, and every third point of the next leaf.
  std::vector<lod::NodeId> leaves, stack{store->root()};
  while (!stack.empty()) {
    const lod::NodeId id = stack.back();
    stack.pop_back();
    if (store->node(id).leaf()) {
      leaves.push_back(id);
    } else {
      for (lod::NodeId c : store->children(id)) stack.push_back(c);
    }
  }
  ASSERT_GE(leaves.size(), 4u);
  Selection s;
  std::map<lod::NodeId, std::vector<glm::dvec3>> by_node;  // export goes by node id
  for (size_t k = 0; k < 4; ++k) {
    const auto chunk = store->decodeChunk(leaves[k]);
    const uint32_t n = uint32_t(chunk->size());
    std::vector<uint64_t> bits((n + 63) / 64, 0);
    for (uint32_t i = 0; i < n; ++i) {
      if (k % 2 == 0 ? i < n / 2 : i % 3 == 0) {
        bits[i / 64] |= uint64_t(1) << (i % 64);
        by_node[leaves[k]].push_back(store->summary().origin + chunk->offset +
                                     glm::dvec3(chunk->positions[i]));
      }
    }
    s.set(leaves[k], NodeSelection::fromBits(n, std::move(bits)));
  }
  std::vector<glm::dvec3> want;
  for (const auto& [node, points] : by_node) want.insert(want.end(), points.begin(), points.end());
  const int64_t place = storeSelection(dir / "notes.tadb", s);
  const std::string sel = " --selection " + (dir / "notes.tadb").string() + ":" + std::to_string(place);
  test::CommandResult r = lod("export " + (dir / "a.tlod").string() + " -o " +
                              (dir / "sel.laz").string() + sel + " --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto out = test::readAll(dir / "sel.laz");
  ASSERT_EQ(out.points.size(), want.size());
  ASSERT_EQ(out.points.size(), s.count());
  for (size_t i = 0; i < want.size(); ++i) {
    ASSERT_LT(glm::length(out.info.origin + out.points.positions[i] - want[i]), 1e-3) << i;
  }
  // The same selection on another store: refused, nothing written.
  b.leaf_max = 100000;
  lod::buildStore({kData + "/lidar/autzen_trim.las"}, dir / "one.tlod", b);
  r = lod("export " + (dir / "one.tlod").string() + " -o " + (dir / "x.las").string() + sel);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("made on another store"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.las"));
  // A scan is not a store.
  r = lod("export " + kData + "/lidar/autzen_trim.las -o " + (dir / "x.las").string() + sel);
  EXPECT_EQ(r.code, 1) << r.out;
  // A place that is a point, a place that does not exist, a bad spec, a file that is no database.
  Place point;
  point.kind = PlaceKind::kPoint;
  point.model = "autzen";
  point.position = glm::dvec3(1, 2, 3);
  const int64_t p2 = AnnotationDb(dir / "notes.tadb").addPlace(point);
  const std::string a = "export " + (dir / "a.tlod").string() + " -o " + (dir / "x.las").string();
  r = lod(a + " --selection " + (dir / "notes.tadb").string() + ":" + std::to_string(p2));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("is not a selected region"), std::string::npos) << r.out;
  r = lod(a + " --selection " + (dir / "notes.tadb").string() + ":999");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("has no place 999"), std::string::npos) << r.out;
  r = lod(a + " --selection " + (dir / "notes.tadb").string());
  EXPECT_EQ(r.code, 2) << r.out;
  r = lod(a + " --selection " + kData + "/lidar/autzen_trim.las:1");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.las"));
}

}  // namespace
}  // namespace tessera::annotate
