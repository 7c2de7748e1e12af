#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""The repository stands on its own (CTest `repository`): every file git tracks is checked,
and each finding is printed as FILE:LINE: what.

(a) No issue-tracker citation: the word "issue" or "issues" followed by a number N, as in
    "issue N", "Issue N, item M", "issue #N", "issue-N", or with N at the start of the next line.
    A reader of the repository has no tracker; say the reason instead. A public project's report
    is cited in GitHub's owner/repo#N form (libnifalcon/libnifalcon#66) or by its URL, which this
    rule does not match.
(b) No citation of a file outside the repository:
    - the lab's background folder: a path that starts with "shared" and goes on into its
      reference, spec or paper folders, or one that climbs into it ("..", then "shared");
    - a machine's own files: an absolute path under /work, /home, /root, /Users, /mnt or
      /media, anywhere (a path that continues a variable or a name, such as
      ${WORK_DIR}/root/usr, is not absolute and is allowed);
    - a file under /tmp, in Markdown or on a comment line. In code, /tmp is a runtime path (a
      default scratch directory) and is allowed; a mktemp template (XXXXXX) is allowed anywhere.
    System interfaces and installed locations (/dev, /sys, /proc, /usr, /etc, /opt, /var, /run,
    /lib, /bin) are not citations and are always allowed.
(c) Every source file carries "SPDX-License-Identifier: Apache-2.0" in its comment syntax on
    its first line, or on its second after a "#!" line. Source files are: C and C++ (.c .cc .cpp
    .h .hpp, and .cpp.in templates), CMake (CMakeLists.txt, .cmake, .cmake.in), Python (.py,
    .pyi), shell and other scripts (a file without an extension whose first line is "#!", or
    .sh), and the viewer's JavaScript and CSS (.js .mjs .ts .vue .css). Left out: third-party or
    generated files (tools/viewer/dist, the page's build output, see THIRD-PARTY-NOTICES.md), data
    (scenes, CSVs, JSON, fuzz corpora) and configuration files.

Outside a git checkout (a source tarball) there is no list of tracked files: the script says so
and exits 77, which CTest reports as skipped (SKIP_RETURN_CODE).

    check_repository.py --source-dir DIR
"""
import argparse
import os
import re
import subprocess
import sys

SKIP = 77
SPDX = "SPDX-License-Identifier: Apache-2.0"

# Third-party or generated trees: no SPDX line of ours belongs there.
NOT_OURS = ("tools/viewer/dist/",)

ISSUE = re.compile(r"\b[Ii]ssues?(?:[ \t]+#?|-|#)\d+")
ISSUE_AT_END = re.compile(r"\b[Ii]ssues?[ \t]*$")
NUMBER_AT_START = re.compile(r"^\s*(?:/{2,}|#+|\*+|<!--)?\s*#?\d+\b")
BACKGROUND = re.compile(r"(?<![\w.-])shared/(?:reference|spec|paper)\b|\.\./shared(?![\w-])")
MACHINE = re.compile(r"(?<![\w.}\])$~*/-])/(?:work|home|root|Users|mnt|media)/")
TMP = re.compile(r"(?<![\w.}\])$~*/-])/tmp/[\w.-]+")
COMMENT_LINE = re.compile(r"^\s*(?://|#|/\*|\*|<!--|--)")

C_LIKE = (".c", ".cc", ".cpp", ".h", ".hpp", ".cpp.in")
CMAKE = (".cmake", ".cmake.in")
PYTHON = (".py", ".pyi")
WEB = (".js", ".mjs", ".ts", ".vue", ".css")


def tracked_files(source_dir: str):
    """The tracked files, or (None, why) when source_dir is not the top of a git checkout."""
    try:
        top = subprocess.run(["git", "-C", source_dir, "rev-parse", "--show-toplevel"], capture_output=True,
                             text=True)
    except FileNotFoundError:
        return None, "git is not installed"
    if top.returncode != 0:
        return None, top.stderr.strip().splitlines()[-1] if top.stderr.strip() else "git rev-parse failed"
    if os.path.realpath(top.stdout.strip()) != os.path.realpath(source_dir):
        return None, f"it lies inside another checkout ({top.stdout.strip()})"
    out = subprocess.run(["git", "-C", source_dir, "ls-files", "-z"], capture_output=True, check=True)
    return [p for p in out.stdout.decode("utf-8").split("\0") if p], ""


def is_source(path: str, first_line: str) -> bool:
    if path.startswith(NOT_OURS):
        return False
    name = os.path.basename(path)
    if name == "CMakeLists.txt" or name.endswith(C_LIKE + CMAKE + PYTHON + WEB) or name.endswith(".sh"):
        return True
    return "." not in name and first_line.startswith("#!")


def spdx_ok(lines: list) -> bool:
    head = lines[:2] if lines and lines[0].startswith("#!") else lines[:1]
    return any(SPDX in line for line in head)


def check_file(path: str, text: str, problems: list) -> None:
    lines = text.split("\n")
    markdown = path.endswith(".md")
    for n, line in enumerate(lines, 1):
        if ISSUE.search(line):
            problems.append(f"{path}:{n}: cites an issue number (say the reason instead): {line.strip()}")
        elif ISSUE_AT_END.search(line) and n < len(lines) and NUMBER_AT_START.match(lines[n]):
            problems.append(f"{path}:{n}: cites an issue number across a line break: {line.strip()}")
        if BACKGROUND.search(line):
            problems.append(f"{path}:{n}: names the lab's background folder, outside the repository: "
                            f"{line.strip()}")
        if MACHINE.search(line):
            problems.append(f"{path}:{n}: names a path on a machine, outside the repository: {line.strip()}")
        elif (markdown or COMMENT_LINE.match(line)) and any("XXXXXX" not in m.group(0) for m in TMP.finditer(line)):
            problems.append(f"{path}:{n}: cites a file under /tmp: {line.strip()}")
    if is_source(path, lines[0] if lines else "") and not spdx_ok(lines):
        problems.append(f"{path}:1: no '{SPDX}' on its first line (after a #! line)")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source-dir", required=True)
    args = parser.parse_args()
    files, why = tracked_files(args.source_dir)
    if files is None:
        print(f"{args.source_dir} is not a git checkout (a source tarball?): {why}; no list of tracked files, "
              "nothing checked (skipped)")
        return SKIP
    problems = []
    checked = 0
    for path in files:
        full = os.path.join(args.source_dir, path)
        if not os.path.isfile(full):
            continue  # deleted in the working tree, or a submodule
        data = open(full, "rb").read()
        if b"\0" in data:
            continue  # binary (PNG)
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            continue
        checked += 1
        check_file(path, text, problems)
    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} problem(s) in {checked} tracked text files")
        return 1
    print(f"{checked} tracked text files: no issue numbers, no paths outside the repository, SPDX lines present")
    return 0


if __name__ == "__main__":
    sys.exit(main())
