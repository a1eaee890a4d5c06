#include <gtest/gtest.h>
#include <tessera/lod/point_reader.h>
TEST(Ply, Placeholder) {}
