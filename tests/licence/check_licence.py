#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""The licence, the third-party notice and the Debian copyright file, checked against what the
build uses (CTest `licence`).

- LICENSE is the Apache License 2.0, word for word (Debian's copy in /usr/share/common-licenses).
- THIRD-PARTY-NOTICES.md has a row for every Debian package tools/debian-packages.txt installs
  and every npm package tools/viewer/package.json names, and no row for one they do not.
- Every shared library the given programs load (readelf's NEEDED) is in a row marked "linked".
- Every row that ships (linked, compiled in, bundled) has a licence that may ship with an
  Apache-2.0 program that way: permissive for code compiled in or bundled; permissive or LGPL
  (or GPL with the GCC runtime exception) for a shared library; never GPL alone.
- cmake/package/debian/copyright is machine-readable (DEP-5): a Format line, every Files
  paragraph with Copyright and License, and a licence text for every licence it names, among
  them those of the code compiled in or bundled.

    check_licence.py --source-dir DIR [--binary PROGRAM ...]
"""
import argparse
import json
import os
import re
import subprocess
import sys

# What may ship, by how (SPDX identifiers; an "A OR B" expression needs one allowed choice).
PERMISSIVE = {"MIT", "BSD-2-Clause", "BSD-3-Clause", "BSL-1.0", "Apache-2.0", "Apache-2.0 WITH LLVM-exception",
              "PSF-2.0", "LicenseRef-Matplotlib (PSF-based, permissive)"}
DYNAMIC = PERMISSIVE | {"LGPL-2.1-only", "LGPL-2.1-or-later", "LGPL-3.0-or-later",
                        "GPL-3.0-or-later WITH GCC-exception-3.1"}
# SPDX identifiers as Debian's copyright format names them.
DEBIAN_NAME = {"MIT": "Expat", "BSD-3-Clause": "BSD-3-clause", "BSL-1.0": "BSL-1.0", "Apache-2.0": "Apache-2.0"}
DEP5_FORMAT = "https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/"


def fail(errors: list, message: str) -> None:
    errors.append(message)


def rows_of(notice: str) -> list:
    rows = []
    for line in notice.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 5 or not line.startswith("|") or cells[0] in ("component", "---"):
            continue
        rows.append(dict(zip(("component", "package", "soname", "use", "licence"), cells)))
    return rows


def debian_packages(path: str) -> set:
    out = set()
    for line in open(path, encoding="utf-8"):
        line = line.split("#", 1)[0].strip()
        if line:
            out.add(line)
    return out


def npm_packages(path: str) -> set:
    data = json.load(open(path, encoding="utf-8"))
    return set(data.get("dependencies", {})) | set(data.get("devDependencies", {}))


def needed(binary: str) -> list:
    r = subprocess.run(["readelf", "-d", binary], capture_output=True, text=True, check=True)
    return re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", r.stdout)


def choices(expression: str) -> list:
    return [c.strip() for c in expression.split(" OR ")]


def check_dep5(text: str, must_name: set, errors: list) -> None:
    paragraphs = [p for p in re.split(r"\n\s*\n", text.strip()) if p.strip()]
    if not paragraphs or not paragraphs[0].startswith(f"Format: {DEP5_FORMAT}"):
        fail(errors, f"copyright: the first line is not 'Format: {DEP5_FORMAT}'")
        return
    named, texts = set(), set()
    for p in paragraphs[1:]:
        fields = {}
        for line in p.splitlines():
            m = re.match(r"^([A-Za-z-]+):\s*(.*)$", line)
            if m:
                fields[m.group(1)] = m.group(2)
        if "Files" in fields:
            for key in ("Copyright", "License"):
                if not fields.get(key):
                    fail(errors, f"copyright: the paragraph for Files: {fields['Files']} has no {key}")
            named |= {n.strip() for n in re.split(r"\s+(?:and|or)\s+", fields.get("License", "")) if n.strip()}
        elif "License" in fields:
            if len(p.splitlines()) < 2:
                fail(errors, f"copyright: License: {fields['License']} has no text")
            texts.add(fields["License"].strip())
    for name in sorted(named - texts):
        fail(errors, f"copyright: no licence text for {name}, which a Files paragraph names")
    for name in sorted(must_name - named):
        fail(errors, f"copyright: {name} (of code compiled in or bundled) is not among its licences")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--source-dir", required=True)
    ap.add_argument("--binary", action="append", default=[])
    args = ap.parse_args()
    src = args.source_dir
    errors: list = []

    licence = open(os.path.join(src, "LICENSE"), encoding="utf-8").read()
    reference = "/usr/share/common-licenses/Apache-2.0"
    if os.path.exists(reference):
        if licence != open(reference, encoding="utf-8").read():
            fail(errors, f"LICENSE differs from {reference}")
    elif "Apache License" not in licence or "Version 2.0, January 2004" not in licence:
        fail(errors, "LICENSE is not the Apache License 2.0")

    rows = rows_of(open(os.path.join(src, "THIRD-PARTY-NOTICES.md"), encoding="utf-8").read())
    if not rows:
        fail(errors, "THIRD-PARTY-NOTICES.md: no table rows")
    listed_debian = {r["package"] for r in rows if not r["package"].endswith("(npm)") and not r["package"].startswith("(")}
    listed_npm = {r["package"][: -len(" (npm)")] for r in rows if r["package"].endswith("(npm)")}
    wanted_debian = debian_packages(os.path.join(src, "tools", "debian-packages.txt"))
    wanted_npm = npm_packages(os.path.join(src, "tools", "viewer", "package.json"))
    for p in sorted(wanted_debian - listed_debian):
        fail(errors, f"THIRD-PARTY-NOTICES.md: no row for Debian package {p} (tools/debian-packages.txt)")
    for p in sorted(listed_debian - wanted_debian):
        fail(errors, f"THIRD-PARTY-NOTICES.md: a row for {p}, which tools/debian-packages.txt does not install")
    for p in sorted(wanted_npm - listed_npm):
        fail(errors, f"THIRD-PARTY-NOTICES.md: no row for npm package {p} (tools/viewer/package.json)")
    for p in sorted(listed_npm - wanted_npm):
        fail(errors, f"THIRD-PARTY-NOTICES.md: a row for npm package {p}, which package.json does not name")

    for binary in args.binary:
        for soname in needed(binary):
            row = next((r for r in rows if soname in [s.strip() for s in r["soname"].split(",")]), None)
            if row is None:
                fail(errors, f"{os.path.basename(binary)} loads {soname}: no row of THIRD-PARTY-NOTICES.md names it")
            elif "linked" not in row["use"]:
                fail(errors, f"{soname} ({row['component']}) is loaded by {os.path.basename(binary)} but its row says '{row['use']}'")

    must_name = set()
    for r in rows:
        use, options = r["use"], choices(r["licence"])
        if "compiled in" in use or "bundled" in use:
            if not any(o in PERMISSIVE for o in options):
                fail(errors, f"{r['component']} is {use} under {r['licence']}: only a permissive licence may be")
            for o in options:
                if o in DEBIAN_NAME and o != "Apache-2.0":
                    must_name.add(DEBIAN_NAME[o])
                    break
        elif "linked" in use and not any(o in DYNAMIC for o in options):
            fail(errors, f"{r['component']} is linked under {r['licence']}: not allowed with an Apache-2.0 program")
    check_dep5(open(os.path.join(src, "cmake", "package", "debian", "copyright"), encoding="utf-8").read(),
               must_name, errors)

    for e in errors:
        print(f"check_licence: {e}", file=sys.stderr)
    if not errors:
        print(f"check_licence: LICENSE, {len(rows)} notice rows, {len(args.binary)} programs' libraries and the "
              "copyright file agree")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
