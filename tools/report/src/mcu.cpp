// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/mcu.hpp"

#include <stdlib.h>  // mkdtemp

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "toonforce/report/process.hpp"
#include "toonforce/report/template.hpp"
#include "toonforce/report/templates.hpp"

// From tools/mcu/images.cmake (tools/report/CMakeLists.txt): the scenes comma-separated.
#if !defined(TOONFORCE_MCU_SCENES) || !defined(TOONFORCE_MCU_ICOUNT_SHIFT)
#error "TOONFORCE_MCU_SCENES and TOONFORCE_MCU_ICOUNT_SHIFT come from tools/mcu/images.cmake"
#endif

namespace toonforce::report {

namespace fs = std::filesystem;

std::vector<std::string> mcu_scenes() {
  std::vector<std::string> scenes;
  std::string_view list = TOONFORCE_MCU_SCENES;
  while (!list.empty()) {
    const auto comma = list.find(',');
    scenes.emplace_back(list.substr(0, comma));
    if (comma == std::string_view::npos) break;
    list.remove_prefix(comma + 1);
  }
  return scenes;
}

int mcu_icount_shift() { return TOONFORCE_MCU_ICOUNT_SHIFT; }

namespace {

/// A QEMU run takes a quarter of a second; a hung image is stopped long before CTest's limit.
constexpr std::chrono::seconds kQemuTimeout{240};
constexpr const char* kBuildImages =
    "tools/setup-deps installs the cross compiler and QEMU, then `cmake --workflow --preset cortex-m3` builds and "
    "checks the images";

/// `path` relative to the source tree when inside it (as a reader of the document types it),
/// else as given.
std::string shown(const fs::path& path, const std::string& root) {
  std::error_code ec;
  const fs::path base = fs::weakly_canonical(fs::absolute(root, ec), ec);
  const fs::path full = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (!ec) {
    const fs::path rel = full.lexically_relative(base);
    if (!rel.empty() && *rel.begin() != "..") return rel.string();
  }
  return path.lexically_normal().string();
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  if (in) text << in.rdbuf();
  return text.str();
}

/// The last `n` non-empty lines of `text`, indented, for an error message.
std::string last_lines(const std::string& text, std::size_t n) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty()) lines.push_back(line);
  }
  std::string out;
  for (std::size_t i = lines.size() > n ? lines.size() - n : 0; i < lines.size(); ++i) out += "\n    " + lines[i];
  return out.empty() ? "\n    (nothing)" : out;
}

/// A scratch directory, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    std::error_code ec;
    std::string pattern = (fs::temp_directory_path(ec) / "toonforce-mcu-XXXXXX").string();
    if (!ec && mkdtemp(pattern.data()) != nullptr) path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// KEY's value in DIR/CMakeCache.txt ("KEY:TYPE=value"), "" if there is none.
std::string cache_value(const fs::path& dir, std::string_view key) {
  std::istringstream in(read_text(dir / "CMakeCache.txt"));
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key, 0) != 0 || line.size() <= key.size() || line[key.size()] != ':') continue;
    const auto eq = line.find('=');
    if (eq != std::string::npos) return line.substr(eq + 1);
  }
  return {};
}

/// The images the tables need: each scene's (the run table) and its size image (the size
/// table); the Cortex-M3 has a size image with all the scenes too (the M4F does not).
std::vector<std::string> needed_images(bool all_scenes) {
  std::vector<std::string> names;
  for (const auto& scene : mcu_scenes()) {
    names.push_back(scene + ".elf");
    names.push_back("size_" + scene + ".elf");
  }
  if (all_scenes) names.emplace_back("size_all_scenes.elf");
  return names;
}

std::vector<std::string> missing_images(const fs::path& dir, bool all_scenes) {
  std::vector<std::string> missing;
  std::error_code ec;
  for (const auto& name : needed_images(all_scenes)) {
    if (!fs::is_regular_file(dir / name, ec)) missing.push_back(name);
  }
  return missing;
}

/// The build directories whose images the report takes by default, in that order.
std::vector<fs::path> default_image_dirs(const std::string& root) {
  return {(fs::path(root) / "build/cortex-m3/tools/mcu/cortex-m3").lexically_normal(),
          (fs::path(root) / "build/release/tools/mcu/cortex-m3").lexically_normal()};
}

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

}  // namespace

std::string default_mcu_images(const std::string& root) {
  // A configured build has the directory before its images are built: the first with images.
  const auto dirs = default_image_dirs(root);
  for (const auto& dir : dirs) {
    if (missing_images(dir, true).size() < needed_images(true).size()) return dir.string();
  }
  return dirs.back().string();
}

namespace {

fs::path m3_images(const McuOptions& options) {
  return options.images.empty() ? fs::path(default_mcu_images(options.root)) : fs::path(options.images);
}

/// How the images in `dir` were built, from where they are: build/cortex-m3 is the cortex-m3
/// preset's, build/release the release build's (its mcu tests build them).
std::string build_command(const fs::path& dir, const std::string& root) {
  const fs::path rel = shown(dir, root);
  const std::vector<fs::path> parts(rel.begin(), rel.end());
  if (parts.size() != 5 || parts[0] != "build" || parts[2] != "tools" || parts[3] != "mcu") return {};
  const std::string preset = parts[1].string();
  if (preset == "cortex-m3") return "cmake --workflow --preset cortex-m3";
  if (preset == "release") return "cmake --workflow --preset release && ctest --preset release -L mcu";
  return {};
}

/// This executable's name (toonforce-lab) at the head of `command` replaced by its path in the
/// source tree (build/cortex-m3/bin/toonforce-lab), when it is there.
std::string with_executable(const std::string& command, const std::string& root) {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return command;
  const std::string name = self.filename().string();
  if (command.rfind(name + " ", 0) != 0) return command;
  const std::string exe = shown(self, root);
  if (fs::path(exe).is_absolute()) return command;
  return exe + command.substr(name.size());
}

/// A value inside a QEMU option list: its commas doubled (a temporary directory may have one).
std::string qemu_option_value(const std::string& value) {
  std::string out;
  for (const char c : value) out += c == ',' ? std::string(",,") : std::string(1, c);
  return out;
}

struct Tools {
  std::string size;
  std::string qemu;
  std::string gen;
};

/// Each size image through arm-none-eabi-size -A, each scene image under QEMU, then the
/// generator's tables.
Result<bool> measure(McuCore& core, const fs::path& dir, bool all_scenes, const Tools& tools, const fs::path& scratch,
                     int shift, const Progress& progress) {
  const fs::path work = scratch / core.cpu;
  std::error_code ec;
  fs::create_directories(work, ec);
  if (ec) return Error{fmt::format("cannot create {}: {}", work.string(), ec.message())};
  std::vector<std::string> gen_argv{tools.gen, "figures"};
  std::vector<std::string> sized = mcu_scenes();
  if (all_scenes) sized.emplace_back("all_scenes");
  for (const auto& name : sized) {
    const fs::path image = dir / ("size_" + name + ".elf");
    const fs::path out = work / ("size_" + name + ".txt");
    const fs::path err = work / ("size_" + name + ".err");
    const std::vector<std::string> argv{tools.size, "-A", image.string()};
    auto status = run_captured(argv, out.string(), err.string());
    if (!status) return Error{status.error()};
    if (status.value() != 0) {
      return Error{fmt::format("`{}` failed with status {}:{}", shell_line(argv), status.value(),
                               last_lines(read_text(err), 10))};
    }
    gen_argv.push_back("--size");
    gen_argv.push_back(name + "=" + out.string());
  }
  for (const auto& scene : mcu_scenes()) {
    const fs::path image = dir / (scene + ".elf");
    const fs::path out = work / (scene + ".txt");
    const fs::path log = work / (scene + ".qemu.txt");
    if (progress) progress(fmt::format("mcu: {} under QEMU ({})", image.string(), core.machine));
    // As run_image.cmake runs it: -icount for exact counts, the output through semihosting
    // into a file, no display, serial or monitor.
    const std::vector<std::string> argv{tools.qemu,
                                        "-machine",
                                        core.machine,
                                        "-cpu",
                                        core.cpu,
                                        "-display",
                                        "none",
                                        "-monitor",
                                        "none",
                                        "-serial",
                                        "none",
                                        "-chardev",
                                        "file,id=out,path=" + qemu_option_value(out.string()),
                                        "-semihosting-config",
                                        "enable=on,target=native,chardev=out",
                                        "-icount",
                                        fmt::format("shift={},align=off,sleep=off", shift),
                                        "-kernel",
                                        image.string()};
    auto status = run_captured(argv, log.string(), log.string(), kQemuTimeout);
    const std::string output = read_text(out);
    const bool finished = output.find("\ndone\n") != std::string::npos;
    if (!status || status.value() != 0 || !finished) {
      const std::string how = !status               ? status.error()
                              : status.value() != 0 ? fmt::format("exit status {}", status.value())
                                                    : "it ended without its \"done\" line";
      return Error{fmt::format(
          "the image {} failed under QEMU ({}).\n  Its last lines:{}\n  QEMU's own output:{}\n  Its command: {}\n"
          "  (its CTest test, mcu_{}_{}, runs it and compares its forces with the host's)",
          image.string(), how, last_lines(output, 8), last_lines(read_text(log), 4), shell_line(argv),
          core.cpu == "cortex-m3" ? "m3" : "m4f", scene)};
    }
    gen_argv.push_back("--run");
    gen_argv.push_back(scene + "=" + out.string());
  }
  const fs::path tables = work / "figures.md";
  const fs::path err = work / "figures.err";
  auto status = run_captured(gen_argv, tables.string(), err.string());
  if (!status) return Error{status.error()};
  if (status.value() != 0) {
    return Error{
        fmt::format("{} figures failed with status {}:{}", tools.gen, status.value(), last_lines(read_text(err), 10))};
  }
  // Two tables, a blank line between them: the sizes, then the instructions per tick.
  const std::string text = read_text(tables);
  const auto gap = text.find("\n\n");
  if (gap == std::string::npos || text.rfind("| image |", 0) != 0 || text.compare(gap + 2, 9, "| scene |") != 0) {
    return Error{
        fmt::format("{} figures printed something other than its two tables:{}", tools.gen, last_lines(text, 6))};
  }
  core.size_table = text.substr(0, gap + 1);
  core.run_table = text.substr(gap + 2);
  core.present = true;
  return true;
}

}  // namespace

std::string mcu_images_missing(const McuOptions& options) {
  const fs::path dir = m3_images(options);
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    if (!options.images.empty()) return fmt::format("no directory {} (--images) ({})", dir.string(), kBuildImages);
  }
  const auto missing = missing_images(dir, true);
  if (missing.size() == needed_images(true).size()) {
    if (!options.images.empty()) return fmt::format("no Cortex-M3 images in {} ({})", dir.string(), kBuildImages);
    const auto dirs = default_image_dirs(options.root);
    return fmt::format("no Cortex-M3 images in {} nor {} ({})", dirs.front().string(), dirs.back().string(),
                       kBuildImages);
  }
  if (!missing.empty()) {
    return fmt::format("{} has not every Cortex-M3 image: {} missing ({})", dir.string(), joined(missing),
                       kBuildImages);
  }
  return {};
}

Result<McuReport> run_mcu(const McuOptions& options, const Progress& progress) {
  McuReport report;
  report.icount_shift = mcu_icount_shift();
  report.command = with_executable(options.command, options.root);
  const fs::path m3_dir = m3_images(options);
  // A directory of the other core's images would run on the wrong board: its cache says which.
  if (const std::string cpu = cache_value(m3_dir, "TOONFORCE_MCU_CPU"); !cpu.empty() && cpu != "cortex-m3") {
    return Error{fmt::format("{} holds {} images (its CMakeCache.txt), not Cortex-M3 ones{}", m3_dir.string(), cpu,
                             cpu == "cortex-m4f" ? ": pass it as --m4f-images, the M3 images as --images" : "")};
  }
  if (const std::string why = mcu_images_missing(options); !why.empty()) return Error{why};
  report.build_command = build_command(m3_dir, options.root);

  Tools tools;
  tools.size = find_program("arm-none-eabi-size");
  if (tools.size.empty()) {
    return Error{"arm-none-eabi-size is not on PATH (Debian's binutils-arm-none-eabi; tools/setup-deps installs it)"};
  }
  tools.qemu = find_program("qemu-system-arm");
  if (tools.qemu.empty()) {
    return Error{"qemu-system-arm is not on PATH (Debian's qemu-system-arm; tools/setup-deps installs it)"};
  }
  const fs::path gen = options.gen.empty() ? m3_dir.parent_path() / "toonforce_mcu_gen" : fs::path(options.gen);
  tools.gen = find_program(gen.string());
  if (tools.gen.empty()) {
    const fs::path build = m3_dir.parent_path().parent_path().parent_path();
    return Error{fmt::format("no toonforce_mcu_gen at {}{}: build it (`cmake --build {} --target toonforce_mcu_gen`; "
                             "the images' build does) or pass --gen",
                             gen.string(), options.gen.empty() ? " (beside the images' directory)" : "",
                             build.empty() ? "BUILD_DIR" : build.string())};
  }

  report.m3.title = "Cortex-M3";
  report.m3.machine = "mps2-an385";
  report.m3.cpu = "cortex-m3";
  report.m3.dir = shown(m3_dir, options.root);
  report.m3.opt = cache_value(m3_dir, "TOONFORCE_MCU_OPT");
  report.m4f.title = "Cortex-M4F";
  report.m4f.machine = "mps2-an386";
  report.m4f.cpu = "cortex-m4";

  const fs::path m4f_dir =
      options.m4f_images.empty() ? m3_dir.parent_path() / "cortex-m4f" : fs::path(options.m4f_images);
  report.m4f.dir = shown(m4f_dir, options.root);
  report.m4f.opt = cache_value(m4f_dir, "TOONFORCE_MCU_OPT");
  std::error_code ec;
  bool m4f = true;
  if (!fs::is_directory(m4f_dir, ec)) {
    if (!options.m4f_images.empty()) {
      return Error{fmt::format("no directory {} (--m4f-images) (`cmake --workflow --preset cortex-m3` builds the "
                               "Cortex-M4F images beside the M3 ones, or the target toonforce_mcu_cortex_m4f)",
                               m4f_dir.string())};
    }
    // Not built (the M3 images can be built alone): said in the section, not pretended.
    m4f = false;
    report.m4f.absent = fmt::format(
        "No Cortex-M4F images in `{}`, so no float figures here: build them beside the M3 ones "
        "(`cmake --workflow --preset cortex-m3`, or the target `toonforce_mcu_cortex_m4f`) and run the command again.",
        report.m4f.dir);
  } else {
    const auto missing = missing_images(m4f_dir, false);
    if (!missing.empty()) {
      return Error{fmt::format("{} has not every Cortex-M4F image: {} missing (build the target "
                               "toonforce_mcu_cortex_m4f, or `cmake --workflow --preset cortex-m3`)",
                               m4f_dir.string(), joined(missing))};
    }
    if (const std::string cpu = cache_value(m4f_dir, "TOONFORCE_MCU_CPU"); !cpu.empty() && cpu != "cortex-m4f") {
      return Error{fmt::format("{} holds {} images (its CMakeCache.txt), not Cortex-M4F ones", m4f_dir.string(), cpu)};
    }
  }

  const TempDir scratch;
  if (scratch.path().empty()) return Error{"cannot create a temporary directory for the images' output"};
  if (auto m = measure(report.m3, m3_dir, true, tools, scratch.path(), report.icount_shift, progress); !m) {
    return Error{m.error()};
  }
  if (m4f) {
    if (auto m = measure(report.m4f, m4f_dir, false, tools, scratch.path(), report.icount_shift, progress); !m) {
      return Error{m.error()};
    }
  }
  return report;
}

std::vector<std::pair<std::string, double>> mcu_loop_mean_instructions(const McuCore& core) {
  const auto cells = [](std::string_view line) {
    std::vector<std::string> out;
    std::size_t start = line.find('|');
    while (start != std::string_view::npos) {
      const std::size_t end = line.find('|', start + 1);
      if (end == std::string_view::npos) break;
      std::string_view cell = line.substr(start + 1, end - start - 1);
      while (!cell.empty() && cell.front() == ' ') cell.remove_prefix(1);
      while (!cell.empty() && cell.back() == ' ') cell.remove_suffix(1);
      out.emplace_back(cell);
      start = end;
    }
    return out;
  };
  std::vector<std::pair<std::string, double>> out;
  std::size_t column = 0;  // 0: the header not seen yet (column 0 is the scene)
  std::size_t start = 0;
  while (start < core.run_table.size()) {
    std::size_t end = core.run_table.find('\n', start);
    if (end == std::string::npos) end = core.run_table.size();
    const std::vector<std::string> row = cells(std::string_view(core.run_table).substr(start, end - start));
    start = end + 1;
    if (row.empty()) continue;
    if (row.front() == "scene") {
      const auto it = std::find(row.begin(), row.end(), "every-stage loop tick, mean");
      column = it == row.end() ? 0 : static_cast<std::size_t>(it - row.begin());
      continue;
    }
    if (column == 0 || column >= row.size() || row.front().rfind("---", 0) == 0) continue;
    char* parsed_end = nullptr;
    const double value = std::strtod(row[column].c_str(), &parsed_end);
    if (parsed_end != row[column].c_str()) out.emplace_back(row.front(), value);
  }
  return out;
}

std::string mcu_markdown(const McuReport& report) {
  const auto opt = [](const McuCore& core) {
    return core.opt.empty() ? std::string("optimisation not known: no CMakeCache.txt beside the images")
                            : fmt::format("`{}`", core.opt);
  };
  std::string md;
  md += fmt::format("<!-- Generated by `{}`; edit tools/report/src/mcu.cpp, not this part. -->\n\n", report.command);
  md += "Commands (the figures are exact: the same on every run and on any machine):\n\n```sh\n";
  if (!report.build_command.empty()) {
    md += fmt::format("{}   # builds every image and checks its forces against the host's replay\n",
                      report.build_command);
  }
  md += fmt::format("{}   # runs them again and regenerates this part\n```\n\n", report.command);
  if (report.build_command.empty()) md += "The images were built as tools/mcu/README.md says. ";
  md += render_prose(templates::mcu_qemu_commands_md, {{"icount_shift", fmt::format("{}", report.icount_shift)}});
  for (const McuCore* core : {&report.m3, &report.m4f}) {
    if (!core->present) {
      md += fmt::format("### {} (QEMU {})\n\n{}\n\n", core->title, core->machine, core->absent);
      continue;
    }
    md += fmt::format("### {} (QEMU {}): image size per scene ({})\n\nImages: `{}`.\n\n{}\n", core->title,
                      core->machine, opt(*core), core->dir, core->size_table);
    md += fmt::format("### {} (QEMU {}): instructions per tick ({})\n\n{}\n", core->title, core->machine, opt(*core),
                      core->run_table);
  }
  // One blank line before the end marker: a table's last row is not followed by the comment.
  while (md.size() >= 3 && md.compare(md.size() - 3, 3, "\n\n\n") == 0) md.pop_back();
  return md;
}

}  // namespace toonforce::report
