// SPDX-License-Identifier: Apache-2.0
// `toonforce-lab report all` rewrites only its own part of each docs/performance/ page: the sections other
// commands measured (the servo loop beside cyclictest, the host simulation's speed) must stay
// byte for byte.
#include <gtest/gtest.h>

#include <string>

#include "toonforce/report/documents.hpp"
#include "toonforce/report/mcu.hpp"

namespace toonforce::report {
namespace {

const std::string kBegin(kBeginMarker);
const std::string kEnd(kEndMarker);

TEST(Documents, AFileWithoutMarkersKeepsItsTextAndGainsTheGeneratedPartAtTheEnd) {
  const std::string existing = "# Performance\n\n## Servo loop\n\n| a | b |\n";
  const std::string merged = merge_generated(existing, "## Generated\n\nnumbers\n");
  EXPECT_EQ(merged.rfind(existing, 0), 0U);  // the old text, unchanged, first
  EXPECT_EQ(merged, existing + "\n" + kBegin + "\n## Generated\n\nnumbers\n" + kEnd + "\n");
}

TEST(Documents, RegeneratingReplacesOnlyWhatIsBetweenTheMarkers) {
  const std::string before = "# Performance\n\nintro\n\n";
  const std::string after = "\n\n## Written by hand, after\n\ntext  with  spaces \n";
  const std::string existing = before + kBegin + "\nold numbers\n" + kEnd + after;
  const std::string merged = merge_generated(existing, "new numbers");
  EXPECT_EQ(merged, before + kBegin + "\nnew numbers\n" + kEnd + after);
  // Idempotent: the same numbers again change nothing.
  EXPECT_EQ(merge_generated(merged, "new numbers"), merged);
}

TEST(Documents, AnEmptyFileGetsJustTheGeneratedPart) {
  EXPECT_EQ(merge_generated("", "x\n"), kBegin + "\nx\n" + kEnd + "\n");
}

// A document written while `report` was toonforce's has its blocks' markers without "-lab": each
// writer takes over its own block (one block, the new markers), never adds a second one, and
// leaves the other blocks' markers and all the prose as they were.
TEST(Documents, MarkersSpeltBeforeTheLabProgramAreAdoptedNotDuplicated) {
  const auto earlier = [](std::string_view marker) {
    std::string m(marker);
    m.erase(m.find("-lab "), 4);
    return m;
  };
  const std::string head = "# Performance\n\nintro\n\n";
  const std::string mcu_block = earlier(kMcuBeginMarker) + "\nmcu numbers\n" + earlier(kMcuEndMarker) + "\n\n";
  const std::string tail = "\n\n## Written by hand, after\n";
  const std::string existing =
      head + mcu_block + earlier(kBeginMarker) + "\nold numbers\n" + earlier(kEndMarker) + tail;
  const std::string adopted = adopt_earlier_markers(existing, kBeginMarker, kEndMarker);
  EXPECT_EQ(adopted, head + mcu_block + kBegin + "\nold numbers\n" + kEnd + tail);
  EXPECT_EQ(merge_generated(adopted, "new numbers"), head + mcu_block + kBegin + "\nnew numbers\n" + kEnd + tail);
  // Present markers, or none: unchanged.
  EXPECT_EQ(adopt_earlier_markers(adopted, kBeginMarker, kEndMarker), adopted);
  EXPECT_EQ(adopt_earlier_markers(head + tail, kBeginMarker, kEndMarker), head + tail);
  // The mcu block's own pair, and only it.
  const std::string mcu_adopted = adopt_earlier_markers(existing, kMcuBeginMarker, kMcuEndMarker);
  EXPECT_EQ(mcu_adopted.find(earlier(kMcuBeginMarker)), std::string::npos);
  EXPECT_NE(mcu_adopted.find(std::string(kMcuBeginMarker) + "\nmcu numbers\n" + std::string(kMcuEndMarker)),
            std::string::npos);
  EXPECT_NE(mcu_adopted.find(earlier(kBeginMarker)), std::string::npos);
}

}  // namespace
}  // namespace toonforce::report
