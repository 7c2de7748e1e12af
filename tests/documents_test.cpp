// SPDX-License-Identifier: Apache-2.0
// `toonforce report all` rewrites only its own part of each docs/performance/ page: the sections other
// commands measured (the servo loop beside cyclictest, the host simulation's speed) must stay
// byte for byte.
#include <gtest/gtest.h>

#include <string>

#include "toonforce/report/documents.hpp"

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

}  // namespace
}  // namespace toonforce::report
