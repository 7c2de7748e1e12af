#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The layers, checked: no include and no link points up.

The allowed graph is written down once, below (LAYERS). Every #include "toonforce/..." in a
layer's sources must name a header of that layer or of one it may use; every library a
target links (build/<preset>/layers/targets.txt, written by cmake/ToonforceLayers.cmake)
must be of such a layer or a system library; the guardian program links no parser, no network
and no report code, by its link closure and by the symbols in its binary.

Usage: check_layers.py SOURCE_DIR TARGETS_TXT [GUARDIAN_BINARY]
Exit status 0 when the tree keeps to the graph, 1 with one line per violation.
"""

import os
import re
import subprocess
import sys

# Layer -> the layers it may include and link (besides itself). A layer is a top-level folder,
# or a backend folder of hal/ or a folder of tools/. Up is never allowed: effects are pure force
# laws; the device seam (hal) knows vectors and scalars; a device backend knows the seam;
# control (time, safety, the loop and its processes) knows effects and the seam, never a backend;
# host_sim knows the seam and the loop's types; tools may use everything below them.
BACKENDS = ["hal/falcon", "hal/gpio", "hal/omni"]
LAYERS = {
    "effects": [],
    "hal": ["effects"],
    "hal/falcon": ["effects", "hal"],
    "hal/gpio": ["effects", "hal"],
    "hal/omni": ["effects", "hal"],
    "control": ["effects", "hal"],
    "host_sim": ["effects", "hal", "control"],
}
BELOW_TOOLS = ["effects", "hal", "control", "host_sim"] + BACKENDS
# Libraries outside the project a layer below tools/ may link: the runtime's, a backend's own
# device library, and fmt (formatting, no parser).
SYSTEM_OK = {
    "effects": {"fmt::fmt"},
    "hal": set(),
    "control": {"fmt::fmt", "Threads::Threads"},
    "host_sim": {"fmt::fmt"},
}
# What the guardian program must not contain: parsers (TOML, JSON, the command line), the
# network (Boost.Asio/Beast), the reports.
GUARDIAN_FORBIDDEN_SYMBOLS = re.compile(r"\b(toml::|nlohmann::|boost::|CLI::|toonforce::config::|toonforce::report|"
                                        r"toonforce::viewer|toonforce::cli::|toonforce::sim::)")


def layer_of(rel):
    """The layer of a path relative to the source tree, or None (tests, examples, docs...)."""
    parts = rel.split("/")
    if parts[0] == "hal":
        if len(parts) > 1 and "hal/" + parts[1] in BACKENDS:
            return "hal/" + parts[1]
        return "hal"
    if parts[0] == "tools":
        return "tools/" + parts[1] if len(parts) > 1 else "tools"
    if parts[0] in ("effects", "control", "host_sim"):
        return parts[0]
    return None


def allowed(src, dst):
    if dst is None or src == dst:
        return True
    if src.startswith("tools"):
        return True  # tools may use every layer, and each other
    return dst in LAYERS.get(src, [])


def header_owners(source):
    """include path ("toonforce/x/y.hpp") -> the layer whose include/ folder holds it."""
    owners = {}
    for top in ("effects", "hal", "control", "host_sim", "tools"):
        for dirpath, _, files in os.walk(os.path.join(source, top)):
            rel_dir = os.path.relpath(dirpath, source)
            if "/include" not in "/" + rel_dir + "/":
                continue
            head, _, tail = ("/" + rel_dir + "/").partition("/include/")
            for f in files:
                key = (tail + f) if tail else f
                owners.setdefault(key.strip("/"), set()).add(layer_of(head.strip("/") + "/x"))
    return owners


def check_includes(source):
    problems = []
    owners = header_owners(source)
    include = re.compile(r'^\s*#\s*include\s*"([^"]+)"')
    for top in ("effects", "hal", "control", "host_sim", "tools"):
        for dirpath, _, files in os.walk(os.path.join(source, top)):
            if "node_modules" in dirpath:
                continue
            for f in files:
                if not f.endswith((".cpp", ".hpp", ".h", ".cc", ".in")):
                    continue
                path = os.path.join(dirpath, f)
                rel = os.path.relpath(path, source)
                src = layer_of(rel)
                with open(path, encoding="utf-8", errors="replace") as text:
                    for number, line in enumerate(text, 1):
                        m = include.match(line)
                        if not m:
                            continue
                        for dst in owners.get(m.group(1), ()):
                            if not allowed(src, dst):
                                problems.append(f"{rel}:{number}: includes {m.group(1)} of {dst}; {src} may use "
                                                f"{', '.join(LAYERS.get(src, [])) or 'nothing below it'}")
    return problems


def read_targets(path):
    targets = {}
    with open(path, encoding="utf-8") as text:
        for line in text:
            name, folder, libs = (line.rstrip("\n").split("\t") + ["", ""])[:3]
            targets[name] = (folder, [l for l in libs.split(";") if l])
    return targets


def check_links(targets):
    problems = []
    for name, (folder, libs) in sorted(targets.items()):
        src = layer_of(folder)
        if src is None or src.startswith("tools"):
            continue
        for lib in libs:
            if lib in targets:
                dst = layer_of(targets[lib][0])
                if lib == "toonforce_warnings":
                    continue
                if not allowed(src, dst):
                    problems.append(f"target {name} ({folder}) links {lib} of {dst}: {src} may link "
                                    f"{', '.join(LAYERS.get(src, [])) or 'nothing below it'}")
            elif src in SYSTEM_OK and lib not in SYSTEM_OK[src] and not lib.startswith("-"):
                problems.append(f"target {name} ({folder}) links the outside library {lib}: {src} may link "
                                f"{', '.join(sorted(SYSTEM_OK[src])) or 'none'}")
    return problems


def closure(targets, name):
    seen, todo = set(), [name]
    while todo:
        t = todo.pop()
        if t in seen:
            continue
        seen.add(t)
        todo.extend(targets.get(t, ("", []))[1])
    return seen


def check_guardian(targets, binary):
    problems = []
    name = "toonforce-guardian"
    if name not in targets:
        return [f"no target {name}"]
    for t in sorted(closure(targets, name) - {name}):
        if t in targets and t != "toonforce_warnings" and layer_of(targets[t][0]) != "control" and \
                layer_of(targets[t][0]) not in LAYERS["control"]:
            problems.append(f"{name} links {t} ({targets[t][0]}): the guardian links the control layer only")
        if t not in targets and t not in SYSTEM_OK["control"]:
            problems.append(f"{name} links the outside library {t}")
    if binary:
        symbols = subprocess.run(["nm", "-C", binary], capture_output=True, text=True, check=False).stdout
        found = sorted({m.group(1) for m in GUARDIAN_FORBIDDEN_SYMBOLS.finditer(symbols)})
        if found:
            problems.append(f"{binary} holds symbols of {', '.join(found)}: a parser, the network or reports")
        dynamic = subprocess.run(["ldd", binary], capture_output=True, text=True, check=False).stdout
        for lib in ("libtomlplusplus", "libboost", "libssl", "libcrypto", "libpython", "libusb", "libgpiod"):
            if lib in dynamic:
                problems.append(f"{binary} loads {lib}")
    return problems


def main(argv):
    if len(argv) < 3:
        print(__doc__)
        return 2
    source, targets_txt = argv[1], argv[2]
    binary = argv[3] if len(argv) > 3 else ""
    targets = read_targets(targets_txt)
    problems = check_includes(source) + check_links(targets) + check_guardian(targets, binary)
    for p in problems:
        print(p)
    print(f"layers: {len(problems)} violation(s); {len(targets)} targets checked")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
