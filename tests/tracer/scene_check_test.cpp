// find_coplanar_overlaps (tracer/scene_check.h): faces in one plane whose image is the ray
// tracer's tie-break are found where a camera ray can reach them, with their meshes and overlap
// area; faces hidden back to back are not; the project's own built-in scenes have none.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <fmt/format.h>

#include "test_util.h"
#include "tracer/scene_check.h"
#include "tracer/scene_loader.h"
#include "tracer/shapes.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

// A 6 x 6 floor at y = 0 (material `floor`) seen from above under a sky, and `extra` objects.
std::string room(const std::string& extra) {
  return "[camera]\neye = [0, 3, 4]\nlook_at = [0, 0, 0]\nvfov = 40\n"
         "[sky]\ncolor = [1, 1, 1]\n"
         "[materials.floor]\nalbedo = [0.5, 0.5, 0.5]\n"
         "[materials.red]\nalbedo = [0.7, 0.1, 0.1]\n"
         "[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n"
         "[[objects]]\ntype = \"quad\"\nname = \"floor\"\nmaterial = \"floor\"\nsize = [6, 6]\n" +
         extra;
}

std::string box(const std::string& name, const std::string& material, const std::string& size,
                const std::string& translate, const std::string& rotate = "[0, 0, 0]") {
  return fmt::format("[[objects]]\ntype = \"box\"\nname = \"{}\"\nmaterial = \"{}\"\nsize = {}\ntranslate = {}\nrotate = {}\n",
                     name, material, size, translate, rotate);
}

// A scene file of `text`, loaded, and what the check finds in it.
struct Checked {
  std::shared_ptr<const Scene> scene;
  std::vector<CoplanarOverlap> found;  // with the default limits
  bool complete = false;
  std::string mesh(unsigned m) const { return scene->meshes.at(m).name; }
};

Checked check(const std::string& text) {
  test::TempDir dir;
  Checked c;
  c.scene = load_scene(test::write_text(dir.file("s.toml"), text));
  c.found = find_coplanar_overlaps(*c.scene, &c.complete);
  return c;
}

std::vector<CoplanarOverlap> overlaps_of(const std::string& text) { return check(text).found; }

TEST(CoplanarOverlaps, AGlassBoxStandingOnTheFloorIsFoundWithItsFootprint) {
  const Checked c = check(room(box("glass_box", "glass", "[0.8, 0.4, 0.5]", "[0.2, 0.2, 0.1]")));
  const auto& found = c.found;
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(c.mesh(found[0].mesh_a), "floor");
  EXPECT_EQ(c.mesh(found[0].mesh_b), "glass_box");
  // The overlap is the box's whole bottom face, 0.8 x 0.5 (float corners: 1e-5 relative).
  EXPECT_NEAR(found[0].area, 0.8 * 0.5, 1e-5);
  EXPECT_NEAR(found[0].where.y, 0.0, 1e-6);
  EXPECT_GE(found[0].where.x, 0.2f - 0.4f);
  EXPECT_LE(found[0].where.x, 0.2f + 0.4f);
}

TEST(CoplanarOverlaps, AGlassBoxFiveMillimetresAboveTheFloorIsNotFound) {
  EXPECT_TRUE(overlaps_of(room(box("glass_box", "glass", "[0.8, 0.4, 0.5]", "[0.2, 0.205, 0.1]"))).empty());
}

TEST(CoplanarOverlaps, AnOpaqueBoxStandingOnTheFloorIsHiddenAndNotReported) {
  // Its bottom and the floor are back to back: no camera ray gets between them, from inside the
  // box or from under the floor.
  EXPECT_TRUE(overlaps_of(room(box("red_box", "red", "[0.8, 0.4, 0.5]", "[0.2, 0.2, 0.1]"))).empty());
}

TEST(CoplanarOverlaps, ARugQuadOnTheFloorIsFoundUnlessItIsOfTheFloorsMaterial) {
  const std::string rug = "[[objects]]\ntype = \"quad\"\nname = \"rug\"\nmaterial = \"{}\"\nsize = [2, 1]\n"
                          "translate = [0.5, 0, 0.5]\n";
  const auto found = overlaps_of(room(fmt::format(fmt::runtime(rug), "red")));
  ASSERT_EQ(found.size(), 1u);
  EXPECT_NEAR(found[0].area, 2.0, 1e-5);
  EXPECT_GE(found[0].pairs, 2u);  // each of the rug's two triangles over one or both of the floor's
  EXPECT_LE(found[0].pairs, 4u);
  EXPECT_TRUE(overlaps_of(room(fmt::format(fmt::runtime(rug), "floor"))).empty());
}

TEST(CoplanarOverlaps, TwoBoxTopsInOnePlaneAreFound) {
  // A red sill reaching into a wall block, their tops both at y = 1.
  const Checked c =
      check(room(box("wall", "floor", "[2, 1, 0.3]", "[0, 0.5, -1]") + box("sill", "red", "[1, 0.04, 0.5]", "[0, 0.98, -0.85]")));
  const auto& found = c.found;
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(c.mesh(found[0].mesh_a), "wall");
  EXPECT_EQ(c.mesh(found[0].mesh_b), "sill");
  EXPECT_NEAR(found[0].where.y, 1.0, 1e-5);
  EXPECT_NEAR(found[0].area, 1.0 * 0.25, 1e-5);  // the sill's top over the wall's: x -0.5 .. 0.5, z -1.1 .. -0.85
}

TEST(CoplanarOverlaps, FacesInOneTiltedPlaneAreFound) {
  // A glass box standing on a tilted floor: the planes are not aligned with any axis.
  rt::Transform tilt;
  tilt.rot_deg = rt::Vec3(20, 35, 0);
  const rt::Vec3 up = tilt.rotate(rt::Vec3(0, 0.2f, 0));
  const std::string rotate = "[20, 35, 0]";
  const std::string text =
      "[camera]\neye = [0, 3, 4]\nlook_at = [0, 0, 0]\nvfov = 40\n[sky]\ncolor = [1, 1, 1]\n"
      "[materials.floor]\nalbedo = [0.5, 0.5, 0.5]\n[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n"
      "[[objects]]\ntype = \"quad\"\nname = \"slope\"\nmaterial = \"floor\"\nsize = [6, 6]\nrotate = " + rotate + "\n" +
      box("glass_box", "glass", "[0.6, 0.4, 0.6]", fmt::format("[{:.9g}, {:.9g}, {:.9g}]", up.x, up.y, up.z), rotate);
  const auto found = overlaps_of(text);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_NEAR(found[0].area, 0.36, 1e-4);
}

TEST(CoplanarOverlaps, StackedFacesStopAtTheWorkLimitWithWhatWasFound) {
  // 100 copies of a red quad on 100 copies of a white one, all in one place: 40,000 pairs of
  // red and white triangles to test, more than a limit of 1000 exact tests allows.
  const std::string stack = "[[objects]]\ntype = \"quad\"\nname = \"{}\"\nmaterial = \"{}\"\nsize = [1, 1]\n"
                            "translate = [0, 0.5, 0]\nrepeat = 100\n";
  const Checked c = check(room(fmt::format(fmt::runtime(stack), "red_stack", "red") +
                               fmt::format(fmt::runtime(stack), "white_stack", "floor")));
  CoplanarCheckLimits limits;
  limits.exact_tests = 1000;
  bool complete = true;
  const auto found = find_coplanar_overlaps(*c.scene, &complete, limits);
  EXPECT_FALSE(complete);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_GE(found[0].pairs, 100u);  // half of the tested pairs overlap in area (the 20,000 of 40,000 below)
  EXPECT_LE(found[0].pairs, 1000u);
  // The default limits examine the same scene in full: each red triangle covers the white
  // triangle of the same half of every copy (100 x 100 x 2 pairs; the other halves meet it
  // along the diagonal only).
  EXPECT_TRUE(c.complete);
  ASSERT_EQ(c.found.size(), 1u);
  EXPECT_EQ(c.found[0].pairs, 20000u);
}

TEST(CoplanarOverlaps, ProbesStopAtTheirBudgetLargestOverlapsFirst) {
  // Twelve rugs of twelve materials apart on the floor, rug k of side 0.03 (k + 1): twelve
  // groups, the largest probed first.
  std::string extra;
  for (int k = 0; k < 12; ++k)
    extra += fmt::format("[materials.rug{0}]\nalbedo = [0.{0:02d}, 0.3, 0.3]\n[[objects]]\ntype = \"quad\"\n"
                         "name = \"rug{0}\"\nmaterial = \"rug{0}\"\nsize = [{1}, {1}]\ntranslate = [{2}, 0, 0]\n",
                         k, 0.03 * (k + 1), -2.5 + 0.45 * k);
  const Checked c = check(room(extra));
  EXPECT_EQ(c.found.size(), 12u);
  EXPECT_TRUE(c.complete);
  CoplanarCheckLimits limits;
  limits.probes = 3;  // each rug is seen from the eye at its first probe
  bool complete = true;
  const auto found = find_coplanar_overlaps(*c.scene, &complete, limits);
  EXPECT_FALSE(complete);
  ASSERT_EQ(found.size(), 3u);
  EXPECT_EQ(c.mesh(found[0].mesh_b), "rug11");
  EXPECT_EQ(c.mesh(found[2].mesh_b), "rug9");
}

TEST(CoplanarOverlaps, AMovingGlassBoxIsFoundWhereTheShutterClosesOnTheFloor) {
  // The box comes down during the shutter and stands on the floor at its close, only.
  const std::string text =
      room(box("glass_box", "glass", "[0.8, 0.4, 0.5]", "[0.2, 0.7, 0.1]") + "translate_end = [0.2, 0.2, 0.1]\n");
  const Checked c = check(text.substr(0, text.find("[sky]")) + "shutter = [0, 1]\n" + text.substr(text.find("[sky]")));
  ASSERT_TRUE(c.scene->meshes.back().moving());
  EXPECT_TRUE(c.found.empty());  // at the open it is half a metre up
  const auto closing = find_coplanar_overlaps(*c.scene, nullptr, {}, ShutterEnd::kClose);
  ASSERT_EQ(closing.size(), 1u);
  EXPECT_TRUE(closing[0].at_close);
  EXPECT_NEAR(closing[0].area, 0.8 * 0.5, 1e-5);
  EXPECT_NEAR(closing[0].where.y, 0.0, 1e-6);
  bool complete = false;
  const auto both = find_coplanar_overlaps_over_shutter(*c.scene, &complete);
  EXPECT_TRUE(complete);
  ASSERT_EQ(both.size(), 1u);
  EXPECT_NE(describe(*c.scene, both[0]).find("where the shutter closes"), std::string::npos) << describe(*c.scene, both[0]);
}

TEST(CoplanarOverlaps, AStillSceneIsCheckedOnceAtTheOpen) {
  // No mesh moves: the check over the shutter is the check at the open.
  const Checked c = check(room(box("glass_box", "glass", "[0.8, 0.4, 0.5]", "[0.2, 0.2, 0.1]")));
  const auto both = find_coplanar_overlaps_over_shutter(*c.scene);
  ASSERT_EQ(both.size(), 1u);
  EXPECT_FALSE(both[0].at_close);
}

TEST(CoplanarOverlaps, TheProjectsBuiltInScenesHaveNone) {
  // The McGuire scenes read OBJ collections from ../shared/scenes, which have such faces (their
  // warnings name them); the project's own scenes must not, at either end of the shutter and in
  // every frame of a sequence.
  int checked = 0, frames = 0;
  for (const std::string& name : builtin_scene_names()) {
    if (name.starts_with("mcguire-")) continue;
    auto scene = load_scene(name);
    for (int frame = 0; frame < std::max(1, scene->frames); ++frame) {
      if (frame > 0) scene = load_scene(name, {.frame = frame});
      bool complete = false;
      const auto found = find_coplanar_overlaps_over_shutter(*scene, &complete);
      EXPECT_TRUE(complete) << name;
      for (const CoplanarOverlap& o : found) ADD_FAILURE() << describe(*scene, o) << " (frame " << frame << ")";
      ++frames;
    }
    ++checked;
  }
  EXPECT_GE(checked, 10);
  EXPECT_GE(frames, checked + 15);  // playroom-sequence's 16 frames
}

}  // namespace
}  // namespace dnb
