# SPDX-License-Identifier: Apache-2.0
"""A generated section of a document: the lines between a begin and an end marker line, which a
tool writes (--write) or checks against what it would write (--check, a CTest), so a figure in
the prose cannot drift from the code (bounds_table.py, stages_table.py)."""
import argparse
import sys


def write_or_check(doc_path: str, begin_marker: str, end_marker: str, want: list, write: bool, tool: str,
                   what: str, fix: str) -> int:
    """0 when written, or when the document's section is `want`; else 1, printing each differing
    line and `fix`, the command that writes it."""
    with open(doc_path) as f:
        doc = f.read().split("\n")
    if doc.count(begin_marker) != 1 or doc.count(end_marker) != 1 or doc.index(begin_marker) > doc.index(end_marker):
        print(f"{tool}: {doc_path} must hold the line '{begin_marker}' once, then '{end_marker}' once", file=sys.stderr)
        return 1
    begin, end = doc.index(begin_marker), doc.index(end_marker)
    if write:
        with open(doc_path, "w") as f:
            f.write("\n".join(doc[:begin + 1] + want + doc[end:]))
        return 0
    have = doc[begin + 1:end]
    if have == want:
        return 0
    for k in range(max(len(have), len(want))):
        h = have[k] if k < len(have) else "(none)"
        w = want[k] if k < len(want) else "(none)"
        if h != w:
            print(f"{tool}: {doc_path} line {begin + 2 + k}:\n  has  {h}\n  want {w}", file=sys.stderr)
    print(f"{tool}: {doc_path}'s {what}: {fix}", file=sys.stderr)
    return 1


def main(tool: str, begin_marker: str, end_marker: str, inputs: str, lines, what: str) -> int:
    """The command line both tools share: --doc DOC (--check | --write) INPUT..., the section
    being lines(INPUTs)."""
    p = argparse.ArgumentParser(prog=f"{tool}.py")
    p.add_argument("--doc", required=True)
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true")
    mode.add_argument("--write", action="store_true")
    p.add_argument(inputs, nargs="+")
    a = p.parse_args()
    paths = getattr(a, inputs)
    return write_or_check(a.doc, begin_marker, end_marker, lines(paths), a.write, tool, what,
                          f"tools/mcu/wcet/{tool}.py --doc {a.doc} --write " + " ".join(paths))
