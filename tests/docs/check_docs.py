#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""The map docs, checked against the tree (CTest `docs`).

- Every repository path that README.md, docs/ARCHITECTURE.md, docs/SAFETY.md and the docs the
  README's content moved to (docs/USAGE.md, docs/NUMBERS.md) name exists: each link's target
  (relative to the document, as a Markdown viewer resolves it; an anchor into a Markdown file
  must be one of its headings) and each word of an inline code span that starts with a
  top-level entry of the repository (`control/...`, `docs/...`, `LICENSE`; repository-relative,
  as the docs write them). Fenced code blocks and HTML comments are not read.
- Every test docs/SAFETY.md names exists. Its tables' `test` column holds backquoted names
  of two forms (the form is also written at the top of SAFETY.md):
    `Suite.Name`  a GoogleTest test: TEST, TEST_F, TEST_P, TYPED_TEST or TYPED_TEST_P
                  (Suite, Name) in a C++ source under tests/;
    `name`        a CTest test: an add_test(NAME name ...) in a CMakeLists.txt or *.cmake file,
                  a name built in a loop (add_test(NAME mcu_m3_${image} ...)) matching its
                  literal parts, or a fuzzer declared with toonforce_add_fuzzer(name ...).
  Every row names at least one test; its `code` column's identifiers after a path
  (`control/include/toonforce/control/engage.hpp` `Engage::gain`) must occur in that file.
- Every relative link of README.md and of every Markdown file under docs/ resolves to a file or
  folder of the repository and, with an #anchor into a Markdown file, to one of its headings
  (GitHub's anchors: lower case, spaces as '-', punctuation other than '-' and '_' dropped).
- Every generated block's begin marker (`<!-- NAME: ... -->`, NAME one whose `<!-- NAME: end -->`
  some document holds, or one of GENERATED) has its end marker after it in the same file, once:
  a generator that finds half a block writes around it or refuses.
- docs/PERFORMANCE.md is the short page of current figures: fewer than PERFORMANCE_LINES lines
  (the methods and the full tables are its detail pages under docs/performance/).

    check_docs.py --source-dir DIR

Exit status 0 when every name resolves, 1 with one line per problem.
"""
import argparse
import os
import re
import sys

DOCS = ["README.md", "docs/ARCHITECTURE.md", "docs/SAFETY.md", "docs/USAGE.md", "docs/NUMBERS.md"]
SAFETY = "docs/SAFETY.md"
PERFORMANCE = "docs/PERFORMANCE.md"
PERFORMANCE_LINES = 300
# The generated blocks' names (the programs that write them: tools/report/src/documents.cpp,
# mcu.cpp, tools/mcu/wcet/bounds_table.py, stages_table.py).
GENERATED = {"toonforce-lab report", "toonforce-lab report precision", "toonforce-lab report mcu", "wcet bounds", "wcet stages"}
MARKER = re.compile(r"<!-- ([a-z][a-z0-9 -]*): (.*?) -->")
# What a repository path in a code span starts with. Fixed, not listed from the disk: a build
# folder inside the source tree (build/release/bin/toonforce) is not part of the repository.
TOP_DIRS = {".ci", "cmake", "control", "docs", "effects", "examples", "hal", "host_sim", "scenes", "tests", "tools"}
TOP_FILES = {"CMakeLists.txt", "CMakePresets.json", "CONTRIBUTING.md", "LICENSE", "README.md",
             "THIRD-PARTY-NOTICES.md"}
SKIP_DIRS = {".git", "node_modules", "dist"}

GTEST = re.compile(r"^\s*(?:TYPED_)?TEST(?:_F|_P)?\s*\(\s*(\w+)\s*,\s*(\w+)\s*\)", re.M)
ADD_TEST = re.compile(r"\badd_test\s*\(\s*NAME\s+([^\s)]+)")
FUZZER = re.compile(r"\btoonforce_add_fuzzer\s*\(\s*(\w+)")
PATH_WORD = re.compile(r"^[A-Za-z0-9_.@+-]+(?:/[A-Za-z0-9_.@+-]*)*$")
IDENT = re.compile(r"^[A-Za-z_]\w*(?:::[A-Za-z_~]\w*)*(?:\(\))?$")
LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
SPAN = re.compile(r"(`+)((?:(?!\n\s*\n)[^`])+?)\1")


def walk(source, suffixes):
    for dirpath, dirnames, files in os.walk(source):
        rel = os.path.relpath(dirpath, source)
        # Build folders in the source tree (build/, build-*/) are not the repository.
        dirnames[:] = [d for d in dirnames if d not in SKIP_DIRS and not (rel == "." and d.startswith("build"))]
        for f in files:
            if f.endswith(suffixes):
                yield os.path.join(dirpath, f)


def prose(text):
    """The document without fenced code blocks and HTML comments (line numbers kept)."""
    text = re.sub(r"<!--.*?-->", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    out, fence = [], None
    for line in text.split("\n"):
        m = re.match(r"^\s*(```+|~~~+)", line)
        if fence is None and m:
            fence = m.group(1)
            out.append("")
        elif fence is not None:
            if line.strip().startswith(fence):
                fence = None
            out.append("")
        else:
            out.append(line)
    return out


def slug(heading):
    """GitHub's anchor of a heading: lower case, code marks and punctuation dropped, spaces as -."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip())
    text = text.replace("`", "").lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    found, seen = set(), {}
    with open(path, encoding="utf-8") as f:
        for line in prose(f.read()):
            m = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
            if m:
                s = slug(m.group(1))
                n = seen.get(s, 0)
                found.add(s if n == 0 else f"{s}-{n}")
                seen[s] = n + 1
    return found


def path_words(span):
    """The words of a code span that name repository paths."""
    for word in re.split(r"[\s=,;()\[\]|\\'\"<>]+", span):
        word = re.sub(r":\d+$", "", word.rstrip(".:"))
        if not word or not PATH_WORD.match(word) or any(c in word for c in "*{}$"):
            continue
        first = word.split("/")[0]
        if first in TOP_DIRS or (first in TOP_FILES and "/" not in word):
            yield word


def check_links(source, doc, lines, problems):
    doc_dir = os.path.dirname(os.path.join(source, doc))
    text = "\n".join(lines)
    line_of = lambda offset: f"{doc}:{text.count(chr(10), 0, offset) + 1}"
    for m in LINK.finditer(text):
        target = m.group(1)
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):
            continue  # http:, https:, mailto:
        file_part, _, anchor = target.partition("#")
        path = os.path.normpath(os.path.join(doc_dir, file_part)) if file_part else os.path.join(source, doc)
        if not os.path.exists(path):
            problems.append(f"{line_of(m.start())}: the link {target} points to nothing")
        elif anchor and path.endswith(".md") and anchor not in anchors(path):
            problems.append(f"{line_of(m.start())}: the link {target}: {os.path.relpath(path, source)} "
                            f"has no heading #{anchor}")


def check_paths(source, doc, lines, problems):
    text = "\n".join(lines)  # a code span may go on over a line break
    line_of = lambda offset: f"{doc}:{text.count(chr(10), 0, offset) + 1}"
    # Link texts out (their targets are checked above), same length so that offsets stay.
    rest = LINK.sub(lambda m: " " * len(m.group(0)), text)
    for m in SPAN.finditer(rest):
        for word in path_words(m.group(2)):
            if not os.path.exists(os.path.join(source, word)):
                problems.append(f"{line_of(m.start())}: `{word}` is not a path of the repository")


def markdown_docs(source):
    """README.md and every Markdown file under docs/, repository-relative, sorted."""
    docs = ["README.md"] if os.path.isfile(os.path.join(source, "README.md")) else []
    docs += sorted(os.path.relpath(p, source) for p in walk(os.path.join(source, "docs"), (".md",)))
    return docs


def check_markers(docs, texts, problems):
    names = set(GENERATED)
    for text in texts.values():
        names.update(m.group(1) for m in MARKER.finditer(text) if m.group(2) == "end")
    for doc in docs:
        text = texts[doc]
        open_at = {}
        for m in MARKER.finditer(text):
            name, what = m.group(1), m.group(2)
            if name not in names:
                continue
            line = f"{doc}:{text.count(chr(10), 0, m.start()) + 1}"
            if what != "end":
                if name in open_at:
                    problems.append(f"{line}: a second begin marker of '{name}' before the end of the one at "
                                    f"{open_at[name]}")
                open_at[name] = line
            elif name in open_at:
                del open_at[name]
            else:
                problems.append(f"{line}: the end marker of '{name}' has no begin marker before it")
        for name, line in open_at.items():
            problems.append(f"{line}: the begin marker of '{name}' has no end marker after it in {doc}")


def gtest_names(source):
    names = set()
    for path in walk(os.path.join(source, "tests"), (".cpp", ".hpp", ".cc", ".h")):
        with open(path, encoding="utf-8", errors="replace") as f:
            names.update(f"{a}.{b}" for a, b in GTEST.findall(f.read()))
    return names


def ctest_names(source):
    exact, patterns = set(), []
    for path in walk(source, ("CMakeLists.txt", ".cmake")):
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read()
        exact.update(FUZZER.findall(text))
        for name in ADD_TEST.findall(text):
            if "${" not in name:
                exact.add(name)
            elif re.sub(r"\$\{[^}]*\}", "", name):  # a name that is only a variable says nothing
                parts = re.split(r"\$\{[^}]*\}", name)
                patterns.append(re.compile("^" + r"\w+".join(re.escape(p) for p in parts) + "$"))
    return exact, patterns


def table_rows(lines):
    """(line number, {column: cell}) of every row of every table with a `test` column."""
    header = None
    for number, line in enumerate(lines, 1):
        if not line.lstrip().startswith("|"):
            header = None
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]
        if header is None:
            header = [c.lower() for c in cells]
        elif all(re.match(r"^:?-+:?$", c) for c in cells if c):
            continue
        elif "test" in header:
            yield number, dict(zip(header, cells))


def check_safety(source, lines, problems):
    gtests = gtest_names(source)
    exact, patterns = ctest_names(source)
    rows = 0
    for number, row in table_rows(lines):
        rows += 1
        where = f"{SAFETY}:{number}"
        names = [m.group(2) for m in SPAN.finditer(row.get("test", ""))]
        if not names:
            problems.append(f"{where}: the row names no test")
        for name in names:
            if "." in name:
                if name not in gtests:
                    problems.append(f"{where}: no TEST/TEST_F/TEST_P/TYPED_TEST({name.replace('.', ', ')}) under tests/")
            elif not re.match(r"^\w+$", name):
                problems.append(f"{where}: `{name}` is neither Suite.Name nor a CTest name")
            elif name not in exact and not any(p.match(name) for p in patterns):
                problems.append(f"{where}: no CTest test {name} (add_test(NAME {name}) in no CMake file)")
        current = None
        for m in SPAN.finditer(row.get("code", "")):
            span = m.group(2)
            if list(path_words(span)) == [span] and os.path.isfile(os.path.join(source, span)):
                with open(os.path.join(source, span), encoding="utf-8", errors="replace") as f:
                    current = (span, f.read())
            elif current and IDENT.match(span):
                last = span.rstrip("()").split("::")[-1]
                if not re.search(r"\b" + re.escape(last) + r"\b", current[1]):
                    problems.append(f"{where}: `{span}` does not occur in {current[0]}")
    if rows == 0:
        problems.append(f"{SAFETY}: no table with a test column")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--source-dir", required=True)
    args = parser.parse_args()
    source = os.path.abspath(args.source_dir)
    problems = []
    for doc in DOCS:
        path = os.path.join(source, doc)
        if not os.path.isfile(path):
            problems.append(f"{doc}: missing")
            continue
        with open(path, encoding="utf-8") as f:
            lines = prose(f.read())
        check_paths(source, doc, lines, problems)
        if doc == SAFETY:
            check_safety(source, lines, problems)
    every = markdown_docs(source)
    texts = {}
    for doc in every:
        with open(os.path.join(source, doc), encoding="utf-8") as f:
            texts[doc] = f.read()
        check_links(source, doc, prose(texts[doc]), problems)
    check_markers(every, texts, problems)
    if PERFORMANCE in texts:
        lines = texts[PERFORMANCE].count("\n") + (0 if texts[PERFORMANCE].endswith("\n") else 1)
        if lines >= PERFORMANCE_LINES:
            problems.append(f"{PERFORMANCE}: {lines} lines, not fewer than {PERFORMANCE_LINES}: it is the short page of "
                            "current figures; methods and full tables go to its pages under docs/performance/")
    else:
        problems.append(f"{PERFORMANCE}: missing")
    problems = list(dict.fromkeys(problems))  # a DOCS file's links are checked twice
    for p in problems:
        print(f"check_docs: {p}", file=sys.stderr)
    if problems:
        return 1
    print(f"check_docs: {len(DOCS)} documents' paths, every test {SAFETY} names, and {len(every)} documents' "
          f"links and generated blocks are sound; {PERFORMANCE} is short")
    return 0


if __name__ == "__main__":
    sys.exit(main())
