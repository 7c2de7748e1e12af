// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce-lab report mcu`: the microcontroller figures of docs/performance/mcu.md
/// (tools/mcu/README.md). For a directory of built Cortex-M3 images (and the Cortex-M4F ones
/// beside it, when built) it runs what the tables need, as tools/mcu/figures used to:
/// `arm-none-eabi-size -A` on each size image, each scene image under `qemu-system-arm` in
/// -icount mode (exact instruction counts), then `toonforce_mcu_gen figures` for the tables.
/// The figures are exact: the same on every run and machine.

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/report/latency.hpp"  // Progress

namespace toonforce::report {

/// The block of docs/performance/mcu.md `toonforce-lab report mcu --docs` regenerates; the page's
/// prose stays outside it.
inline constexpr std::string_view kMcuBeginMarker = "<!-- toonforce-lab report mcu: begin -->";
inline constexpr std::string_view kMcuEndMarker = "<!-- toonforce-lab report mcu: end -->";

struct McuOptions {
  std::string root;        ///< source tree: the default image directories are under it
  std::string images;      ///< the Cortex-M3 images; empty: default_mcu_images(root)
  std::string m4f_images;  ///< the Cortex-M4F images; empty: the sibling cortex-m4f (if absent, the section says so)
  std::string gen;         ///< toonforce_mcu_gen; empty: <images>/../toonforce_mcu_gen
  std::string command;     ///< the `toonforce-lab report mcu ...` line written into the section
};

/// The paper scenes with an image each, and QEMU's -icount shift: tools/mcu/images.cmake's
/// TOONFORCE_MCU_SCENES and TOONFORCE_MCU_ICOUNT_SHIFT, compiled in by CMake (the images are
/// built from the same file).
std::vector<std::string> mcu_scenes();
int mcu_icount_shift();

/// root/build/cortex-m3/tools/mcu/cortex-m3 (the cortex-m3 preset's) if it has images,
/// else root/build/release/tools/mcu/cortex-m3.
std::string default_mcu_images(const std::string& root);

/// Empty if the Cortex-M3 images `options` names (or the default) are all there; else why not,
/// in one sentence naming what is missing and how to build it (`report all` prints it and
/// goes on without the section).
std::string mcu_images_missing(const McuOptions& options);

/// One core's figures.
struct McuCore {
  std::string title;    ///< "Cortex-M3"
  std::string machine;  ///< QEMU's -machine
  std::string cpu;      ///< QEMU's -cpu
  std::string dir;      ///< the images, as shown in the document
  bool present = false;
  std::string absent;  ///< when not present: the sentence the section prints instead
  std::string opt;     ///< the images' optimisation (their CMakeCache's TOONFORCE_MCU_OPT), "" if unknown
  std::string size_table;
  std::string run_table;
};

struct McuReport {
  std::string command;        ///< the report's command, as written into the section
  std::string build_command;  ///< how the images were built, "" if not known
  int icount_shift = 0;
  McuCore m3;
  McuCore m4f;
};

Result<McuReport> run_mcu(const McuOptions& options, const Progress& progress = {});

/// Per scene, the every-stage loop tick's mean instructions (a core's run table, column
/// "every-stage loop tick, mean": Q16.16 on the Cortex-M3, the mean over the scene's 1 kHz
/// motions). Empty if the table has no such column. For the precision report's closed loop.
std::vector<std::pair<std::string, double>> mcu_loop_mean_instructions(const McuCore& core);

/// The generated block's text (between the markers): the commands, then per core its size
/// table and its instructions table.
std::string mcu_markdown(const McuReport& report);

}  // namespace toonforce::report
