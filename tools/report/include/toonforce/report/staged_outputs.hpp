// SPDX-License-Identifier: Apache-2.0
#pragma once
/// How `report` writes its documents, CSVs and plots: never in place. Each step
/// (latency, precision, stability, mcu) writes every file it makes under a hidden name beside
/// the file's place (same directory, same extension, so a plot script still knows the format),
/// then renames them all over their places at its end. A full disk, a failed plot or a stop
/// signal therefore leaves each file as it was or whole, and a step's files agree with each
/// other; the hidden files are removed whatever happens.
///
/// install_report_stop_handlers() gives `report` (toonforce-lab) and `check` (toonforce) a stop path: on any stop signal
/// (stop_signals()) the program the step waits for (plot, valgrind, QEMU) is killed, the hidden
/// files are removed, the command says which signal stopped it and that no file was left cut,
/// and exits 1. Everything the handler does is async-signal-safe (kill, waitpid, unlink, write).

#include <filesystem>
#include <string>
#include <vector>

#include <sys/types.h>

#include "toonforce/common/result.hpp"

namespace toonforce::report {

class StagedOutputs {
 public:
  StagedOutputs() = default;
  StagedOutputs(const StagedOutputs&) = delete;
  StagedOutputs& operator=(const StagedOutputs&) = delete;
  /// Removes every staged file that was not committed.
  ~StagedOutputs();

  /// The hidden path `target`'s new content is to be written to (by this process or by a
  /// program it runs); committed with the others.
  Result<std::filesystem::path> stage(const std::filesystem::path& target);
  /// Stages `target` and writes `text` to it whole; the staged path (for a program that reads
  /// it before the commit). A failed write says why; the staged file goes with the others.
  Result<std::filesystem::path> write(const std::filesystem::path& target, const std::string& text);
  /// Renames every staged file over its target, in the order staged; the targets.
  Result<std::vector<std::string>> commit();

 private:
  struct Entry {
    std::filesystem::path staged;
    std::filesystem::path target;
    int slot = -1;  // in the stop handler's table
  };
  std::vector<Entry> entries_;
};

/// Installs the stop handlers described above. The message is "COMMAND: stopped by SIGNAL; LEFT",
/// COMMAND the program and its subcommand ("toonforce check"); both must outlive the process
/// (literals).
void install_report_stop_handlers(const char* command, const char* left);
inline constexpr const char* kReportLeaves =
    "no file was left cut (each is as it was, or whole from a step that had finished)";

/// The child the report waits for (0: none), for the stop handler to kill. Set by run_process.
void set_waited_child(pid_t pid) noexcept;

}  // namespace toonforce::report
