# SPDX-License-Identifier: Apache-2.0
"""Experiment files (TOML) of `toonforce study`: conditions as named scene variants,
the design, and one procedure per block. Checked when read, with file:line: key errors as the
scene files' are. The keys are in docs/STUDIES.md.
"""

from __future__ import annotations

import hashlib
import os
import re
import tomllib
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

LEVEL_PROCEDURES = ("staircase", "weighted-staircase", "constant-stimuli")
PROCEDURES = LEVEL_PROCEDURES + ("rating", "paired-comparison", "task")
TASKS = ("hold-still", "strike", "cross")
SCALES = ("likert", "semantic-differential")
RULES = {"1-up-2-down": (1, 2), "1-up-3-down": (1, 3), "2-up-1-down": (2, 1)}


class ExperimentError(ValueError):
    def __init__(self, path: str, line: int, key: str, message: str):
        super().__init__(f"{path}:{line}: {key}: {message}" if line else f"{path}: {key}: {message}")
        self.path, self.line, self.key = path, line, key


@dataclass
class Condition:
    name: str
    scene: str  # absolute path
    vary: str = ""  # the scene key a procedure's level sets, e.g. "surface1.slippery.mu"
    overrides: Dict[str, Any] = field(default_factory=dict)


@dataclass
class Block:
    name: str
    procedure: str
    reference: str  # level procedures: the reference interval's condition ("" otherwise)
    test: str  # level procedures: the test interval's condition, whose `vary` key takes the level
    options: Dict[str, Any]


@dataclass
class Experiment:
    path: str
    text: str
    name: str
    seed: Optional[int]
    order: str  # "latin-square", "fixed", "random"
    script: str  # the hand script of each interval (absolute path)
    quantity: str  # the trace's quantity a simulated observer perceives
    conditions: Dict[str, Condition]
    blocks: List[Block]

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.text.encode("utf-8")).hexdigest()

    def block_order(self, participant: int, rng_seed: int) -> List[int]:
        """The order of the blocks for a participant: a balanced Latin square's row (Williams
        design for an even count) by participant number, as given, or shuffled from the seed."""
        n = len(self.blocks)
        if self.order == "fixed" or n == 1:
            return list(range(n))
        if self.order == "random":
            import random

            order = list(range(n))
            random.Random(rng_seed).shuffle(order)
            return order
        # Williams: first row 0, 1, n-1, 2, n-2, ...; row r adds r to each (mod n).
        first, lo, hi = [0], 1, n - 1
        while len(first) < n:
            first.append(lo)
            lo += 1
            if len(first) < n:
                first.append(hi)
                hi -= 1
        row = participant % n
        return [(b + row) % n for b in first]


def _line_of(text: str, key: str, table: str = "", index: int = 0) -> int:
    """The line of `key = ` inside the index-th [[table]] (or at the top), 0 if not found."""
    lines = text.splitlines()
    start, end, seen = 0, len(lines), -1
    if table:
        for i, line in enumerate(lines):
            if re.match(rf"\s*\[\[\s*{re.escape(table)}\s*\]\]", line):
                seen += 1
                if seen == index:
                    start = i
                    break
        else:
            return 0
        for j in range(start + 1, len(lines)):
            if re.match(r"\s*\[", lines[j]):
                end = j
                break
    for i in range(start, end):
        if re.match(rf"\s*{re.escape(key)}\s*=", lines[i]):
            return i + 1
    return start + 1 if table else 0


def load(path: str) -> Experiment:
    path = os.path.abspath(path)
    with open(path, encoding="utf-8") as f:
        text = f.read()
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        match = re.search(r"line (\d+)", str(e))
        raise ExperimentError(path, int(match.group(1)) if match else 0, "(syntax)", str(e)) from None
    here = os.path.dirname(path)

    def fail(key, message, table="", index=0):
        raise ExperimentError(path, _line_of(text, key.split(".")[-1], table, index), key, message)

    known_top = {"name", "seed", "order", "script", "quantity", "condition", "block"}
    for key in data:
        if key not in known_top:
            fail(key, f"unknown key (known: {', '.join(sorted(known_top))})")
    if not isinstance(data.get("name"), str) or not data["name"]:
        fail("name", "required: the experiment's name")
    seed = data.get("seed")
    if seed is not None and (not isinstance(seed, int) or seed < 0):
        fail("seed", "a non-negative integer (omitted: one is drawn and recorded)")
    order = data.get("order", "latin-square")
    if order not in ("latin-square", "fixed", "random"):
        fail("order", "one of latin-square, fixed, random")
    script = data.get("script")
    if not isinstance(script, str):
        fail("script", "required: the hand script of each interval (a path)")
    script = os.path.normpath(os.path.join(here, script))
    if not os.path.isfile(script):
        fail("script", f"no such file: {script}")
    quantity = data.get("quantity", "mean_along_motion_force")
    if quantity not in QUANTITIES:
        fail("quantity", f"one of {', '.join(QUANTITIES)}")

    conditions: Dict[str, Condition] = {}
    for i, c in enumerate(data.get("condition", [])):
        for key in c:
            if key not in ("name", "scene", "vary", "overrides"):
                fail(f"condition[{i + 1}].{key}", "unknown key (known: name, scene, vary, overrides)", "condition", i)
        name = c.get("name")
        if not isinstance(name, str) or not name or name in conditions:
            fail(f"condition[{i + 1}].name", "required, and unique", "condition", i)
        scene = os.path.normpath(os.path.join(here, str(c.get("scene", ""))))
        if not os.path.isfile(scene):
            fail(f"condition[{i + 1}].scene", f"no such file: {scene}", "condition", i)
        conditions[name] = Condition(name, scene, str(c.get("vary", "")), dict(c.get("overrides", {})))
    if not conditions:
        fail("condition", "at least one [[condition]]")

    blocks: List[Block] = []
    for i, b in enumerate(data.get("block", [])):
        where = ("block", i)
        name = b.get("name", f"block {i + 1}")
        procedure = b.get("procedure")
        if procedure not in PROCEDURES:
            fail(f"block[{i + 1}].procedure", f"one of {', '.join(PROCEDURES)}", *where)
        options = {k: v for k, v in b.items() if k not in ("name", "procedure", "reference", "test")}
        allowed = {
            "staircase": {"rule", "start", "step", "min", "max", "reversals", "discard", "max_trials"},
            "weighted-staircase": {"target", "start", "step", "min", "max", "reversals", "discard", "max_trials"},
            "constant-stimuli": {"levels", "repetitions", "form"},
            "rating": {"conditions", "items", "repetitions"},
            "paired-comparison": {"pairs", "question", "repetitions"},
            "task": {"conditions", "repetitions", "task", "script", "instructions", "after", "hold", "speed_tolerance",
                     "fall_depth", "target", "direction", "until"},
        }[procedure]
        for key in list(b) if procedure not in LEVEL_PROCEDURES else []:
            if key in ("reference", "test"):
                fail(f"block[{i + 1}].{key}", f"not a key of {procedure} (its conditions are in its own keys)", *where)
        for key in options:
            if key not in allowed:
                fail(f"block[{i + 1}].{key}", f"not a key of {procedure} (known: {', '.join(sorted(allowed))})", *where)
        if procedure in LEVEL_PROCEDURES:
            for role in ("reference", "test"):
                if b.get(role) not in conditions:
                    fail(f"block[{i + 1}].{role}", f"a condition's name ({', '.join(conditions)})", *where)
            if not conditions[b["test"]].vary:
                fail(f"block[{i + 1}].test", f"condition '{b['test']}' has no `vary` key for the level", *where)
        if procedure == "staircase" and options.get("rule", "1-up-2-down") not in RULES:
            fail(f"block[{i + 1}].rule", f"one of {', '.join(RULES)}", *where)
        if procedure in ("constant-stimuli", "rating", "paired-comparison", "task"):
            if not isinstance(options.get("repetitions"), int) or options["repetitions"] < 1:
                fail(f"block[{i + 1}].repetitions", "an integer >= 1", *where)
        if procedure == "constant-stimuli":
            levels = options.get("levels")
            if not isinstance(levels, list) or len(levels) < 3 or any(
                    not isinstance(x, (int, float)) or x <= 0 for x in levels):
                fail(f"block[{i + 1}].levels", "at least 3 levels, each > 0", *where)
            if options.get("form", "weibull") not in ("weibull", "logistic"):
                fail(f"block[{i + 1}].form", "weibull or logistic", *where)
        elif procedure == "rating":
            named = options.get("conditions")
            if not isinstance(named, list) or len(named) < 2 or any(c not in conditions for c in named):
                fail(f"block[{i + 1}].conditions", f"two or more conditions' names ({', '.join(conditions)})", *where)
            items = options.get("items")
            if not isinstance(items, list) or not items:
                fail(f"block[{i + 1}].items", "at least one item: {name, scale, points, anchors}", *where)
            for j, item in enumerate(items):
                ok = (isinstance(item, dict) and isinstance(item.get("name"), str) and item.get("scale") in SCALES
                      and isinstance(item.get("points"), int) and 3 <= item["points"] <= 11 and item["points"] % 2 == 1
                      and isinstance(item.get("anchors"), list) and len(item["anchors"]) == 2)
                if not ok:
                    fail(f"block[{i + 1}].items[{j + 1}]", f"name, scale ({' or '.join(SCALES)}), points (odd, 3 to "
                         "11) and anchors (two words: the scale's ends)", *where)
        elif procedure == "task":
            named = options.get("conditions")
            if not isinstance(named, list) or not named or any(c not in conditions for c in named):
                fail(f"block[{i + 1}].conditions", f"one or more conditions' names ({', '.join(conditions)})", *where)
            if options.get("task") not in TASKS:
                fail(f"block[{i + 1}].task", f"one of {', '.join(TASKS)}", *where)
            if "script" in options:
                options["script"] = os.path.normpath(os.path.join(here, str(options["script"])))
                if not os.path.isfile(options["script"]):
                    fail(f"block[{i + 1}].script", f"no such file: {options['script']}", *where)
            for key in ("after", "until", "hold", "speed_tolerance", "fall_depth"):
                if key in options and (not isinstance(options[key], (int, float)) or options[key] < 0):
                    fail(f"block[{i + 1}].{key}", "a number >= 0", *where)
            for key in ("target", "direction"):
                if key in options and (not isinstance(options[key], list) or len(options[key]) != 3 or any(
                        not isinstance(x, (int, float)) for x in options[key])):
                    fail(f"block[{i + 1}].{key}", "three numbers [x, y, z] (m; a direction need not be a unit)", *where)
        elif procedure == "paired-comparison":
            pairs = options.get("pairs")
            if not isinstance(pairs, list) or not pairs or any(
                    not isinstance(p, list) or len(p) != 2 or p[0] == p[1] or any(c not in conditions for c in p)
                    for p in pairs):
                fail(f"block[{i + 1}].pairs", f"pairs of two different conditions ({', '.join(conditions)})", *where)
            if not isinstance(options.get("question"), str) or not options["question"]:
                fail(f"block[{i + 1}].question", "the question asked after each pair", *where)
        else:
            for key in ("start", "step", "min", "max"):
                if not isinstance(options.get(key), (int, float)):
                    fail(f"block[{i + 1}].{key}", "required: a number", *where)
        blocks.append(Block(name, procedure, b.get("reference", ""), b.get("test", ""), options))
    if not blocks:
        fail("block", "at least one [[block]]")
    return Experiment(path, text, data["name"], seed, order, script, quantity, conditions, blocks)


def _mean_along_motion_force(trace) -> float:
    """The scene's force along the handle's motion [N], averaged over the ticks that slide in
    contact (|v| > 2 cm/s): positive pushes (cartoon ice), negative drags (friction)."""
    import numpy as np

    speed = np.hypot(trace["vx"], trace["vy"])
    sliding = (speed > 0.02) & (trace["contact"] > 0)
    if not np.any(sliding):
        return 0.0
    along = (trace["scene_fx"] * trace["vx"] + trace["scene_fy"] * trace["vy"]) / np.maximum(speed, 1e-12)
    return float(np.mean(along[sliding]))


QUANTITIES = {"mean_along_motion_force": _mean_along_motion_force}


def task_metrics(task: str, trace, options: Dict[str, Any]) -> Dict[str, Any]:
    """A task's metrics from a trace (SI units), up to `until` [s] if given: `path_length_m`
    (the handle's path) and per task:
      hold-still  from `after` [s] on, the handle must stay under `speed_tolerance` [m/s,
                  default 0.005] for `hold` [s, default 0.3]: success, time_to_still_s (from
                  `after`), drift_m (the path after `after`), and with `target` (the point the
                  hand stops at, m) overshoot_m: how far past it the handle went along
                  `direction` (default +x) from `after` on (negative: it stopped short);
      strike      peak_force_n (the largest commanded force), overshoot_m (the deepest the
                  handle went below the surface at z = 0), success (it touched);
      cross       min_z_m, success (never deeper than `fall_depth` [m, default 0.01])."""
    import numpy as np

    t = np.asarray(trace["t"], dtype=float)
    if "until" in options:  # the task's window ends there (before the hand lets go, say)
        keep = t <= float(options["until"])
        trace = {k: np.asarray(v)[keep] for k, v in trace.items() if np.ndim(v) == 1 and len(v) == len(keep)}
        t = t[keep]
    p = np.stack([trace["x"], trace["y"], trace["z"]], axis=1)
    steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
    out: Dict[str, Any] = {"path_length_m": float(steps.sum())}
    if task == "hold-still":
        after, hold, tol = (float(options.get("after", 0.0)), float(options.get("hold", 0.3)),
                            float(options.get("speed_tolerance", 0.005)))
        speed = np.linalg.norm(np.stack([trace["vx"], trace["vy"], trace["vz"]], axis=1), axis=1)
        start = int(np.searchsorted(t, after))
        out["drift_m"] = float(steps[start:].sum())
        if "target" in options:
            direction = np.asarray(options.get("direction", [1.0, 0.0, 0.0]), dtype=float)
            direction = direction / np.linalg.norm(direction)
            past = (p[start:] - np.asarray(options["target"], dtype=float)) @ direction
            out["overshoot_m"] = float(past.max()) if past.size else None
        still_since = None
        out["success"], out["time_to_still_s"] = False, None
        for i in range(start, t.size):
            if speed[i] < tol:
                still_since = t[i] if still_since is None else still_since
                if t[i] - still_since >= hold:
                    out["success"], out["time_to_still_s"] = True, float(still_since - after)
                    break
            else:
                still_since = None
    elif task == "strike":
        force = np.linalg.norm(np.stack([trace["fx"], trace["fy"], trace["fz"]], axis=1), axis=1)
        out.update(peak_force_n=float(force.max()), overshoot_m=float(max(0.0, -p[:, 2].min())),
                   success=bool(p[:, 2].min() < 0))
    else:
        out.update(min_z_m=float(p[:, 2].min()), success=bool(p[:, 2].min() > -float(options.get("fall_depth", 0.01))))
    return out
