#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""CTest install_files: the installed product holds nothing of the lab.

The lab (docs/ARCHITECTURE.md, "The lab") is built and tested but never installed: the report
program toonforce-lab and its library, toonforce_tick_count, the benchmarks, the Cortex-M
images' generator and WCET analysis (tools/mcu), the report plots' script plot_report.py, the
report library's headers. This installs a build tree with `cmake --install` for each component
the Debian packages are made of (CPACK_COMPONENTS_ALL, cmake/ToonforcePackaging.cmake) into a
scratch prefix, lists every file, and fails when:
  - a file's path is one of the lab's (LAB_PATHS below);
  - the installed toonforce defines a toonforce::report:: symbol that the library
    toonforce::report_outputs does not (`nm -C --defined-only`): how `check` writes and stops
    (staged_outputs.hpp) is the product's, everything else of toonforce::report is the lab's;
  - the installed toonforce holds the build's source tree's path other than as one of the
    KNOWN_SOURCE_PATHS (a path of the build machine is no use where it is installed). A path the
    compiler builds from immediates (short strings) is not found this way; the symbol check is
    the one that holds report code out.

With --listing FILE it checks only the paths in FILE (one a line), for the Debian packages'
contents (tests/install/deb_test.cmake).

Usage:
  check_install_files.py --build-dir B --source-dir S --work-dir W --cmake CMAKE --nm NM
                         --report-outputs LIB.a --component C [--component C ...]
  check_install_files.py --listing FILE
Exit status 0 when clean, 1 with one line per problem.
"""

import argparse
import os
import re
import shutil
import subprocess
import sys

# What of the lab an install could carry, by path (relative to the staging root or the package).
LAB_PATHS = [
    (re.compile(r"(^|/)toonforce-lab$"), "the lab's program toonforce-lab"),
    (re.compile(r"(^|/)toonforce_mcu_gen$"), "the Cortex-M images' generator"),
    (re.compile(r"(^|/)toonforce_tick_count$"), "the report's callgrind program"),
    (re.compile(r"(^|/)toonforce_[a-z_]*bench$"), "a benchmark (tools/bench)"),
    (re.compile(r"(^|/)plot_report\.py$"), "the report plots' script"),
    (re.compile(r"(^|/)tools/mcu(/|$)"), "the Cortex-M images' folder"),
    (re.compile(r"wcet", re.IGNORECASE), "the WCET analysis (tools/mcu/wcet)"),
    (re.compile(r"(^|/)toonforce/report/"), "a header of the report library"),
    (re.compile(r"(^|/)libtoonforce_report[^/]*\.a$"), "the report library"),
]

# The source tree's path as tools/sim keeps it in every program linking it: a build tree's
# binary's fallback for its scenes and plot script when no installed data is found beside it
# (data_dir.hpp, build_source_dir(): one string, ended where the path ends; what it needs under
# it is appended at run time). Known, not wanted. Any other occurrence (the path inside a longer
# string) fails.
KNOWN_SOURCE_PATHS = [""]

# The documentation is the product's: it may describe the lab's measurements (the pages under
# share/doc/.../performance/ on the WCET analysis), so the lab's names are not looked for in it.
DOC_PATH = re.compile(r"(^|/)share/doc/[^/]+/.*\.(md|png|svg|csv)$")


def lab_path_problems(paths):
    problems = []
    for path in paths:
        if DOC_PATH.search(path):
            continue
        for pattern, what in LAB_PATHS:
            if pattern.search(path):
                problems.append(f"{path}: {what} is the lab's, never installed")
                break
    return problems


def defined_report_symbols(nm, path):
    out = subprocess.run([nm, "-C", "--defined-only", path], check=True, capture_output=True, text=True).stdout
    symbols = set()
    for line in out.splitlines():
        parts = line.split(None, 2)
        if len(parts) == 3 and "toonforce::report::" in parts[2]:
            symbols.add(parts[2])
    return symbols


def unknown_source_paths(binary, source_dirs):
    """The NUL-terminated strings of `binary` holding one of `source_dirs` not as a known path."""
    with open(binary, "rb") as f:
        data = f.read()
    found = set()
    for src in source_dirs:
        needle = src.encode()
        at = data.find(needle)
        while at != -1:
            start = data.rfind(b"\0", 0, at) + 1
            end = data.find(b"\0", at)
            end = end if end != -1 else len(data)
            rest = data[at + len(needle):end].decode("utf-8", "replace")
            known = any(rest == k if not k else rest.startswith(k) for k in KNOWN_SOURCE_PATHS)
            if not known:
                found.add(data[start:end].decode("utf-8", "replace"))
            at = data.find(needle, at + 1)
    return found


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--listing")
    parser.add_argument("--build-dir")
    parser.add_argument("--source-dir")
    parser.add_argument("--work-dir")
    parser.add_argument("--cmake", default="cmake")
    parser.add_argument("--nm", default="nm")
    parser.add_argument("--report-outputs")
    parser.add_argument("--component", action="append", default=[])
    args = parser.parse_args()

    if args.listing:
        with open(args.listing, encoding="utf-8") as f:
            paths = [line.strip() for line in f if line.strip()]
        problems = lab_path_problems(paths)
        for p in problems:
            print(p)
        return 1 if problems else 0

    for name in ("build_dir", "source_dir", "work_dir", "report_outputs"):
        if not getattr(args, name):
            parser.error(f"--{name.replace('_', '-')} is needed")
    if not args.component:
        parser.error("--component is needed (one per component the packages are made of)")

    shutil.rmtree(args.work_dir, ignore_errors=True)
    prefix = os.path.join(args.work_dir, "usr")
    for component in args.component:
        subprocess.run([args.cmake, "--install", args.build_dir, "--prefix", prefix, "--component", component],
                       check=True, stdout=subprocess.DEVNULL)
    paths = []
    for dirpath, _, files in os.walk(args.work_dir):
        for f in files:
            paths.append(os.path.relpath(os.path.join(dirpath, f), args.work_dir))
    paths.sort()
    print(f"{len(paths)} files installed for the components {', '.join(args.component)}")

    problems = lab_path_problems(paths)

    binary = os.path.join(prefix, "bin", "toonforce")
    if not os.path.isfile(binary):
        problems.append(f"{binary}: not installed (the runtime component must hold the program)")
    else:
        allowed = defined_report_symbols(args.nm, args.report_outputs)
        report = sorted(defined_report_symbols(args.nm, binary) - allowed)
        for symbol in report[:20]:
            problems.append(f"usr/bin/toonforce defines {symbol}: report code (not toonforce::report_outputs)")
        if len(report) > 20:
            problems.append(f"usr/bin/toonforce: {len(report) - 20} more toonforce::report:: symbols")
        sources = {os.path.abspath(args.source_dir), os.path.realpath(args.source_dir)}
        for text in sorted(unknown_source_paths(binary, sources)):
            problems.append(f"usr/bin/toonforce holds the build machine's source path: {text[:200]!r}")

    for p in problems:
        print(p)
    if not problems:
        print("no file of the lab installed; toonforce defines no report code and no new source path")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
