// A site's note edits at the master (collab/site_notes.h) on a real SQLite file: an update
// without a layer keeps the item's own, an image item is not rewritten by a site, and a stale
// revision is a conflict that changes nothing.
#include <tessera/collab/site_notes.h>

#include <gtest/gtest.h>

#include <tessera/collab/site_messages.h>

#include "../support/temp_dir.h"

namespace tessera::collab {
namespace {

class SiteNotes : public ::testing::Test {
 protected:
  void SetUp() override {
    file = dir.path() / "notes.tadb";
    annotate::AnnotationDb db(file);
    annotate::Place p;
    p.model = "scene";
    p.position = {0.1, 0.2, 0.3};
    place = db.addPlace(p);
    annotate::Item text;
    text.layer = "survey/2026";
    text.title = "crack";
    text.text = "along the base";
    text_item = db.addItem(text, "archive");
    db.attach(text_item, place);
    annotate::Item image;
    image.layer = "photos";
    image.kind = annotate::ItemKind::kImage;
    image.title = "1962 photo";
    image.mime = "image/png";
    image.data = {0x89, 'P', 'N', 'G', 1, 2, 3};
    image_item = db.addItem(image, "archive");
    db.attach(image_item, place);
  }

  static site::SiteNote update(int64_t item, uint64_t base, const std::string& layer,
                               const std::string& title) {
    site::SiteNote n;
    n.set_request(7);
    site::NoteUpdate& u = *n.mutable_update();
    u.set_item(uint64_t(item));
    u.set_base_revision(base);
    u.mutable_content()->set_layer(layer);
    u.mutable_content()->set_kind("text");
    u.mutable_content()->set_title(title);
    u.mutable_content()->set_text("along the base, 40 cm");
    return n;
  }

  tessera::test::TempDir dir;
  std::filesystem::path file;
  int64_t place = 0, text_item = 0, image_item = 0;
};

TEST_F(SiteNotes, AnUpdateWithoutALayerKeepsTheItemsLayer) {
  annotate::AnnotationScene notes(file);
  sync::SceneGraph graph;
  notes.load(graph);
  const site::SiteNote n = update(text_item, 1, "", "crack, measured");
  site::ToMaster m;  // a site may leave the layer out of an update, not out of an add
  *m.mutable_note() = n;
  ASSERT_FALSE(checkToMaster(m)) << *checkToMaster(m);
  site::ToMaster add;
  add.mutable_note()->mutable_add()->set_place(uint64_t(place));
  add.mutable_note()->mutable_add()->mutable_item()->set_kind("text");
  add.mutable_note()->mutable_add()->mutable_item()->set_title("no layer");
  ASSERT_TRUE(checkToMaster(add));
  EXPECT_NE(checkToMaster(add)->find("layer"), std::string::npos) << *checkToMaster(add);
  const site::SiteNoteAnswer a = applySiteNote(&notes, graph, "kyoto", n);
  ASSERT_TRUE(a.ok()) << a.error();
  EXPECT_EQ(a.revision(), 2u);
  const auto item = notes.db().item(text_item);
  ASSERT_TRUE(item);
  EXPECT_EQ(item->layer, "survey/2026");
  EXPECT_EQ(item->title, "crack, measured");
  EXPECT_EQ(item->text, "along the base, 40 cm");
  EXPECT_EQ(item->author, "kyoto");
  // A layer named moves it, as before.
  const site::SiteNoteAnswer moved =
      applySiteNote(&notes, graph, "kyoto", update(text_item, 2, "survey/2027", "crack"));
  ASSERT_TRUE(moved.ok()) << moved.error();
  EXPECT_EQ(notes.db().item(text_item)->layer, "survey/2027");
}

TEST_F(SiteNotes, AnImageItemIsNotRewrittenByASite) {
  annotate::AnnotationScene notes(file);
  sync::SceneGraph graph;
  notes.load(graph);
  const site::SiteNoteAnswer a =
      applySiteNote(&notes, graph, "kyoto", update(image_item, 1, "", "a photo"));
  EXPECT_FALSE(a.ok());
  EXPECT_FALSE(a.conflict());
  EXPECT_NE(a.error().find("is an image"), std::string::npos) << a.error();
  const auto item = notes.db().item(image_item);
  ASSERT_TRUE(item);
  EXPECT_EQ(item->kind, annotate::ItemKind::kImage);
  EXPECT_EQ(item->title, "1962 photo");
  EXPECT_EQ(item->data.size(), 7u);
  EXPECT_EQ(item->revision, 1);
}

TEST_F(SiteNotes, AStaleRevisionIsAConflictThatChangesNothing) {
  annotate::AnnotationScene notes(file);
  sync::SceneGraph graph;
  notes.load(graph);
  ASSERT_TRUE(applySiteNote(&notes, graph, "kyoto", update(text_item, 1, "", "first")).ok());
  const site::SiteNoteAnswer late =
      applySiteNote(&notes, graph, "leiden", update(text_item, 1, "", "second"));
  EXPECT_FALSE(late.ok());
  EXPECT_TRUE(late.conflict());
  EXPECT_EQ(notes.db().item(text_item)->title, "first");
  EXPECT_EQ(notes.db().item(text_item)->revision, 2);
}

}  // namespace
}  // namespace tessera::collab
