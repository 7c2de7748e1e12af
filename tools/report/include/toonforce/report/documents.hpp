// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce-lab report all`: runs the latency, precision and stability reports and regenerates
/// their blocks of the detail pages under docs/performance/ (kLatencyDocument,
/// kPrecisionDocument; only between their markers, e.g.
///   <!-- toonforce-lab report: begin --> ... <!-- toonforce-lab report: end -->
/// everything else is kept byte for byte, so sections other commands measured stay as they were) and
/// docs/STABILITY.md (entirely), with their CSVs and plots in <out>/report/. The CLI's `report
/// all` also regenerates the microcontroller block (write_mcu_documents) when the Cortex-M3
/// images are built (tools/lab).

#include <string>

#include "toonforce/common/result.hpp"
#include "toonforce/report/latency.hpp"
#include "toonforce/report/mcu.hpp"
#include "toonforce/report/precision.hpp"
#include "toonforce/report/stability.hpp"

namespace toonforce::report {

/// The pages the generated blocks live in, relative to the documents directory (`--docs`,
/// `--out`): docs/PERFORMANCE.md itself is the short page of current figures, written by hand,
/// that links them. Their plots stay in <documents>/report/, one level up from these pages.
inline constexpr std::string_view kLatencyDocument = "performance/tick.md";
inline constexpr std::string_view kPrecisionDocument = "performance/precision.md";
inline constexpr std::string_view kMcuDocument = "performance/mcu.md";

inline constexpr std::string_view kBeginMarker = "<!-- toonforce-lab report: begin -->";
inline constexpr std::string_view kEndMarker = "<!-- toonforce-lab report: end -->";
/// The precision report's own block (kPrecisionDocument), so `toonforce-lab report precision --docs`
/// regenerates it alone (the latency block is a benchmark of its own).
inline constexpr std::string_view kPrecisionBeginMarker = "<!-- toonforce-lab report precision: begin -->";
inline constexpr std::string_view kPrecisionEndMarker = "<!-- toonforce-lab report precision: end -->";

struct DocumentsOptions {
  std::string out_dir = "docs";
  std::string root;  ///< source tree (scenes/)
  LatencyOptions latency;
  PrecisionOptions precision;
  StabilityOptions stability;
  bool plot = true;
  std::string command_line;  ///< how this run was asked for, written into the documents
};

/// Returns the lines it wrote (files).
Result<std::vector<std::string>> write_documents(const DocumentsOptions& options, const Progress& progress = {});

/// The stability report alone (`toonforce-lab report stability --out DIR`): OUT/STABILITY.md and
/// its CSVs and plots in OUT/report/, leaving the performance pages alone. Returns the files written.
Result<std::vector<std::string>> write_stability_documents(const DocumentsOptions& options,
                                                           const Progress& progress = {});
/// `existing` with the text between the markers replaced by `generated` (markers kept); if it
/// has no markers, `existing` followed by the markers around `generated`.
std::string merge_generated(const std::string& existing, const std::string& generated,
                            std::string_view begin_marker = kBeginMarker, std::string_view end_marker = kEndMarker);

/// `text` with a block's markers as they were spelt before the report became the lab's program
/// (the same without "-lab") put in their present spelling, when it has them and not the present
/// ones; otherwise `text` unchanged. Each writer adopts its own block's markers before it looks
/// for them, so a document written before keeps one block, never gains a second one.
std::string adopt_earlier_markers(std::string text, std::string_view begin_marker, std::string_view end_marker);

/// Writes the precision report's CSVs and plots into <out_dir>/report/ and its block of
/// <out_dir>/performance/precision.md (after the main generated block if it has none yet and the
/// page holds that one). Returns the files written.
Result<std::vector<std::string>> write_precision_documents(const PrecisionReport& precision, const std::string& out_dir,
                                                           const std::string& command_line, bool plot);

/// Regenerates the microcontroller block of <out_dir>/performance/mcu.md (kMcuBeginMarker ...
/// kMcuEndMarker; everything outside it kept byte for byte). With no block yet, it goes at the
/// end under a "## Microcontroller" heading. Returns the files written.
/// Regenerates only the latency block of OUT/performance/tick.md (`toonforce-lab report latency --docs`):
/// the timing tables want a quiet machine, the other reports do not.
Result<std::vector<std::string>> write_latency_documents(const LatencyReport& latency, const std::string& out_dir,
                                                         const std::string& command_line);
Result<std::vector<std::string>> write_mcu_documents(const McuReport& mcu, const std::string& out_dir);

}  // namespace toonforce::report
