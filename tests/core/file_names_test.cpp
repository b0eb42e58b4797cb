// core/file_names.h: the one rule for names that become path components.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/errors.h"
#include "core/file_names.h"
#include "test_util.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;

TEST(FileNames, CheckedKeepsFileNamesAndRefusesEverythingThatCouldLeaveTheFolder) {
  for (const char* ok : {"quick", "proposed-paper", "oidn_cleanaux", "a.b", "x+y", "a..b", "9"})
    EXPECT_EQ(file_names::checked(ok, "here"), ok);
  for (const std::string& bad : std::vector<std::string>{"", ".", "..", "../x", "a/b", "/abs", "a\\b", ".hidden", "-rf", "a b", "tab\t",
                                std::string(121, 'a'), std::string("nul\0x", 5)}) {
    const std::string e = test::error_of<InputError>([&] { file_names::checked(bad, "c.toml:3: key 'name'"); });
    EXPECT_THAT(e, HasSubstr("c.toml:3: key 'name'")) << bad;
    EXPECT_THAT(e, HasSubstr("expected 1 to 120 letters, digits")) << bad;
  }
}

TEST(FileNames, MappedAlwaysGivesAFileNameAndLeavesFileNamesAlone) {
  EXPECT_EQ(file_names::mapped("cornell-box"), "cornell-box");
  EXPECT_EQ(file_names::mapped("scenes/my box.toml"), "scenes_my_box.toml");
  EXPECT_EQ(file_names::mapped(".."), "_.");
  EXPECT_EQ(file_names::mapped("."), "_");
  EXPECT_EQ(file_names::mapped(""), "_");
  EXPECT_EQ(file_names::mapped("-x"), "_x");
  for (const std::string& s : std::vector<std::string>{"../../x", "/abs/../p", std::string(300, 'z'), std::string(300, '/'), "\xc3\xa9t\xc3\xa9"})
    EXPECT_TRUE(file_names::is_file_name(file_names::mapped(s))) << s;
  // Long names keep their start and differ by their hash.
  const std::string a = file_names::mapped(std::string(200, 'a') + "1"), b = file_names::mapped(std::string(200, 'a') + "2");
  EXPECT_EQ(a.size(), file_names::kMaxLength);
  EXPECT_NE(a, b);
}

}  // namespace
}  // namespace dnb
