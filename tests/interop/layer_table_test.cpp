// The layer table (core/aov_frame.h's layer::table()) is the one list of a frame's layers: full
// names resolve to it only where a frame can hold them, every other reader derives from it, and
// docs/design.md's channel table names each layer where the table places it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "core/aov_frame.h"
#include "interop/import.h"
#include "test_util.h"

namespace dnb {
namespace {

TEST(LayerTable, FullNamesResolveOnlyWhereAFrameHoldsTheLayer) {
  ASSERT_NE(layer::find("depth"), nullptr);
  EXPECT_EQ(layer::find("depth")->channels, 1);
  EXPECT_EQ(layer::find("refl2.depth")->channels, 1);
  EXPECT_NE(layer::find("half1.normal"), nullptr);
  EXPECT_NE(layer::find("refl8.tint"), nullptr);
  EXPECT_EQ(layer::find("tint"), nullptr);            // a bounce weight into a level: not at level 0
  EXPECT_EQ(layer::find("refl9.direct"), nullptr);    // beyond the tracer's levels
  EXPECT_EQ(layer::find("refl0.direct"), nullptr);    // level 0 is the bare name
  EXPECT_EQ(layer::find("half0.reflection"), nullptr);
  EXPECT_EQ(layer::find("half2.color"), nullptr);
  EXPECT_EQ(layer::find("refl1.variance"), nullptr);  // variances are level 0's
  EXPECT_EQ(layer::find("colour"), nullptr);
  EXPECT_EQ(default_channels("half0.depth"), 1);
  EXPECT_EQ(default_channels("refl3.samples"), 1);
  EXPECT_THAT(layer::names_help(), ::testing::HasSubstr("indirect_variance"));
}

TEST(LayerTable, TheImportersLayersAreTheImportableOnes) {
  std::vector<std::string> want;
  for (const auto& i : layer::table())
    if (i.importable) want.push_back(i.name);
  EXPECT_EQ(interop::mappable_layers(), want);
  EXPECT_THAT(want, ::testing::Contains("variance"));
  EXPECT_THAT(want, ::testing::Not(::testing::Contains("edge")));
}

// Each layer of the table is a row of docs/design.md's channel table (or named in the rows of
// reflection levels and half buffers exactly where the table puts it).
TEST(LayerTable, DesignDocNamesEveryLayerWhereTheTablePlacesIt) {
  std::ifstream in(test::source_dir() + "/docs/design.md");
  ASSERT_TRUE(in) << "docs/design.md";
  std::string line, levels_row, halves_row, own_rows;
  while (std::getline(in, line)) {
    if (line.rfind("| `refl<K>.<layer>`", 0) == 0) levels_row = line;
    else if (line.rfind("| `half<H>.<layer>`", 0) == 0) halves_row = line;
    else if (line.rfind("| `refl<K>.", 0) == 0) levels_row += line;  // refl<K>.tint's own row
    else if (line.rfind("| `", 0) == 0) own_rows += line.substr(0, line.find(" | ", 2)) + "\n";
  }
  ASSERT_FALSE(levels_row.empty());
  ASSERT_FALSE(halves_row.empty());
  for (const auto& i : layer::table()) {
    const std::string quoted = "`" + std::string(i.name) + "`";
    EXPECT_EQ(own_rows.find(quoted) != std::string::npos, i.level0) << i.name << " at level 0";
    const bool in_levels = levels_row.find(quoted) != std::string::npos || levels_row.find("`refl<K>." + std::string(i.name) + "`") != std::string::npos;
    EXPECT_EQ(in_levels, i.levels) << i.name << " at reflection levels";
    EXPECT_EQ(halves_row.find(quoted) != std::string::npos, i.halves) << i.name << " in the half buffers";
  }
}

}  // namespace
}  // namespace dnb
