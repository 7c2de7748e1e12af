# SPDX-License-Identifier: Apache-2.0
"""Experiment files (TOML) of `toonforce study`: conditions as named scene variants,
the design, and one procedure per block. Checked when read, with file:line: key errors as the
scene files' are. The keys are in docs/STUDIES.md.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

LEVEL_PROCEDURES = ("staircase", "weighted-staircase", "constant-stimuli")
PROCEDURES = LEVEL_PROCEDURES + ("rating", "paired-comparison", "task")
TASKS = ("hold-still", "strike", "cross")
SCALES = ("likert", "semantic-differential")
# Levitt (1971): `down` correct answers in a row step down, `up` wrong ones step up; the track
# settles where P(correct)^down = 1/2 (1-up) or (1 - P(correct))^up = 1/2 (n-up-1-down).
RULES = {"1-up-2-down": (1, 2), "1-up-3-down": (1, 3)}
# A 2-up-1-down rule settles where (1 - P)^2 = 1/2, P = 29.3 % correct: below the 50 % a guess
# gets in two intervals, so in 2IFC its track runs down to `min` and stays there.
BELOW_CHANCE_RULES = {"2-up-1-down": (2, 1)}
DEVICES = ("sim", "falcon", "omni")
STAIRCASE_KEYS = ("start", "step", "min", "max", "reversals", "discard", "max_trials")
# What the participant's page says, by procedure (person.py): the text during each interval,
# the question after the intervals, and the two answer buttons of two-interval questions.
PAGE_KEYS = {
    **{p: ("instructions", "question", "answers") for p in LEVEL_PROCEDURES},
    "paired-comparison": ("instructions", "question", "answers"),
    "rating": ("instructions", "question"),
    "task": ("instructions",),
}
# The page's words where the file gives none (a level procedure's question fits the example
# study, cartoon ice: docs/STUDIES.md).
_TWO = {"instructions": "Stroke across the surface.", "question": "Which interval pushed your hand along?",
        "answers": ("the first", "the second")}
PAGE_DEFAULTS = {**{p: _TWO for p in LEVEL_PROCEDURES}, "paired-comparison": _TWO,
                 "rating": {"instructions": "Explore the surface.", "question": "How was it?"},
                 "task": {"instructions": ""}}
START_TEXT = "When you are ready, press Start."


def page_text(block: "Block", key: str) -> Any:
    """What the page says for the block (`instructions`, `question`, `answers`): the file's
    words, or the default."""
    value = block.options.get(key, PAGE_DEFAULTS[block.procedure][key])
    return list(value) if isinstance(value, (list, tuple)) else value


class ExperimentError(ValueError):
    def __init__(self, path: str, line: int, key: str, message: str):
        super().__init__(f"{path}:{line}: {key}: {message}" if line else f"{path}: {key}: {message}")
        self.path, self.line, self.key = path, line, key


def file_sha256(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


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

    def conditions(self) -> List[str]:
        """The conditions its trials present, in the order the experiment file names them."""
        if self.procedure in LEVEL_PROCEDURES:
            return [self.reference, self.test]
        if self.procedure == "paired-comparison":
            return [c for pair in self.options["pairs"] for c in pair]
        return list(self.options["conditions"])


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
    # Every scene and hand script it uses (absolute path: SHA-256 of its bytes); empty when
    # loaded without its files (a session's copy, for the analysis).
    files: Dict[str, str] = field(default_factory=dict)
    instructions: str = START_TEXT  # the participant's page before Start

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.text.encode("utf-8")).hexdigest()

    def used_conditions(self) -> List[str]:
        """The conditions some block presents, in the order the blocks name them."""
        out: List[str] = []
        for b in self.blocks:
            out += [c for c in b.conditions() if c not in out]
        return out

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
    else:  # top-level keys come before the first table
        end = next((i for i, line in enumerate(lines) if re.match(r"\s*\[", line)), len(lines))
    for i in range(start, end):
        if re.match(rf"\s*{re.escape(key)}\s*=", lines[i]):
            return i + 1
    return start + 1 if table else 0


def _number(value: Any) -> bool:
    """A finite number (a TOML bool is not one; nan and inf are refused)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _integer(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _effect_path(path: Any) -> bool:
    pattern = r"(surface|cliff)[1-9][0-9]*(\.[A-Za-z_][A-Za-z0-9_]*)+"
    return isinstance(path, str) and re.fullmatch(pattern, path) is not None


def load(path: str, text: Optional[str] = None, *, files: bool = True, device: str = "sim") -> Experiment:
    """Reads and checks an experiment file; the first mistake raises ExperimentError naming the
    file, the line and the key. `text`: the file's text (a session's copy) instead of reading
    `path` (paths stay relative to `path`). `files`: also load every scene and hand script it
    names, with each level a procedure can set and each condition's overrides, as a session on
    `device` ("sim", "falcon", "omni") would, and check that the conditions the blocks present
    share one list of effects (a run on a device keeps its scene's); False: the text alone (the
    analysis of a finished session, whose files may have moved)."""
    path = os.path.abspath(path)
    if text is None:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        match = re.search(r"line (\d+)", str(e))
        raise ExperimentError(path, int(match.group(1)) if match else 0, "(syntax)", str(e)) from None
    here = os.path.dirname(path)

    def fail(key, message, table="", index=0):
        raise ExperimentError(path, _line_of(text, key.split(".")[-1].split("[")[0], table, index), key, message)

    known_top = {"name", "seed", "order", "script", "quantity", "instructions", "condition", "block"}
    for key in data:
        if key not in known_top:
            fail(key, f"unknown key (known: {', '.join(sorted(known_top))})")
    if not isinstance(data.get("name"), str) or not data["name"]:
        fail("name", "required: the experiment's name")
    seed = data.get("seed")
    if seed is not None and (not _integer(seed) or seed < 0):
        fail("seed", "a non-negative integer (omitted: one is drawn and recorded)")
    order = data.get("order", "latin-square")
    if order not in ("latin-square", "fixed", "random"):
        fail("order", "one of latin-square, fixed, random")
    script = data.get("script")
    if not isinstance(script, str) or not script:
        fail("script", "required: the hand script of each interval (a path)")
    script = os.path.normpath(os.path.join(here, script))
    if files and not os.path.isfile(script):
        fail("script", f"no such file: {script}")
    instructions = data.get("instructions", START_TEXT)
    if not isinstance(instructions, str) or not instructions.strip():
        fail("instructions", f"text: what the page says before the participant presses Start (got {instructions!r})")
    quantity = data.get("quantity", "mean_along_motion_force")
    if quantity not in QUANTITIES:
        fail("quantity", f"one of {', '.join(QUANTITIES)}")
    if not isinstance(data.get("condition", []), list):
        fail("condition", "an array of tables: [[condition]]")
    if not isinstance(data.get("block", []), list):
        fail("block", "an array of tables: [[block]]")

    conditions: Dict[str, Condition] = {}
    lines: Dict[str, int] = {}  # a condition's [[condition]] index, for messages
    for i, c in enumerate(data.get("condition", [])):
        where = ("condition", i)
        for key in c:
            if key not in ("name", "scene", "vary", "overrides"):
                fail(f"condition[{i + 1}].{key}", "unknown key (known: name, scene, vary, overrides)", *where)
        name = c.get("name")
        if not isinstance(name, str) or not name or name in conditions:
            fail(f"condition[{i + 1}].name", "required, and unique", *where)
        if not isinstance(c.get("scene"), str) or not c["scene"]:
            fail(f"condition[{i + 1}].scene", "required: the condition's scene file (a path)", *where)
        scene = os.path.normpath(os.path.join(here, c["scene"]))
        if files and not os.path.isfile(scene):
            fail(f"condition[{i + 1}].scene", f"no such file: {scene}", *where)
        vary = c.get("vary", "")
        if vary != "" and not _effect_path(vary):
            fail(f"condition[{i + 1}].vary", "an effect's key, as surface1.slippery.mu (KINDn.key.key)", *where)
        overrides = c.get("overrides", {})
        if not isinstance(overrides, dict):
            fail(f"condition[{i + 1}].overrides", 'a table of effect keys: { "surface1.stiffness" = 1200.0 }', *where)
        for key, value in overrides.items():
            if not _effect_path(key):
                fail(f"condition[{i + 1}].overrides", f"'{key}': an effect's key, as surface1.stiffness", *where)
            if isinstance(value, float) and not math.isfinite(value):
                fail(f"condition[{i + 1}].overrides", f"'{key}': a finite number (got {value})", *where)
        conditions[name] = Condition(name, scene, vary, dict(overrides))
        lines[name] = i
    if not conditions:
        fail("condition", "at least one [[condition]]")

    blocks: List[Block] = []
    for i, b in enumerate(data.get("block", [])):
        where = ("block", i)
        k = f"block[{i + 1}]"
        name = b.get("name", f"block {i + 1}")
        if not isinstance(name, str) or not name:
            fail(f"{k}.name", "a name (text)", *where)
        procedure = b.get("procedure")
        if procedure not in PROCEDURES:
            fail(f"{k}.procedure", f"one of {', '.join(PROCEDURES)}", *where)
        options = {key: v for key, v in b.items() if key not in ("name", "procedure", "reference", "test")}
        allowed = {
            "staircase": {"rule", *STAIRCASE_KEYS},
            "weighted-staircase": {"target", *STAIRCASE_KEYS},
            "constant-stimuli": {"levels", "repetitions", "form"},
            "rating": {"conditions", "items", "repetitions"},
            "paired-comparison": {"pairs", "repetitions"},
            "task": {"conditions", "repetitions", "task", "script", "after", "hold", "speed_tolerance",
                     "fall_depth", "target", "direction", "until"},
        }[procedure] | set(PAGE_KEYS[procedure])
        if procedure == "task" and "question" in options:
            fail(f"{k}.question", "a task asks nothing after its interval: what the participant reads is its "
                 "`instructions`", *where)
        if procedure == "rating" and "answers" in options:
            fail(f"{k}.answers", "a rating's answers are its items' points: each item's `anchors` name the ends",
                 *where)
        for key in list(b) if procedure not in LEVEL_PROCEDURES else []:
            if key in ("reference", "test"):
                fail(f"{k}.{key}", f"not a key of {procedure} (its conditions are in its own keys)", *where)
        for key in options:
            if key not in allowed:
                fail(f"{k}.{key}", f"not a key of {procedure} (known: {', '.join(sorted(allowed))})", *where)
        for key in ("instructions", "question"):
            if key in options and (not isinstance(options[key], str) or not options[key].strip()):
                fail(f"{k}.{key}", f"text shown to the participant (got {options[key]!r})", *where)
        if "answers" in options:
            answers = options["answers"]
            if (not isinstance(answers, list) or len(answers) != 2
                    or any(not isinstance(a, str) or not a.strip() for a in answers) or answers[0] == answers[1]):
                fail(f"{k}.answers", f"two different texts, the buttons for the first and the second interval "
                     f"(got {answers!r})", *where)
        if procedure in LEVEL_PROCEDURES:
            for role in ("reference", "test"):
                if not isinstance(b.get(role), str) or b.get(role) not in conditions:
                    fail(f"{k}.{role}", f"a condition's name ({', '.join(conditions)})", *where)
            if b["reference"] == b["test"]:
                fail(f"{k}.test", "the test condition must differ from the reference: the intervals would be alike",
                     *where)
            if not conditions[b["test"]].vary:
                fail(f"{k}.test", f"condition '{b['test']}' has no `vary` key for the level", *where)
        if procedure == "staircase":
            rule = options.get("rule", "1-up-2-down")
            if rule in BELOW_CHANCE_RULES:
                fail(f"{k}.rule", f"{rule} converges on 29.3 % correct, below the 50 % of guessing in two intervals: "
                     f"its track would run down to `min` and stay there (use {' or '.join(RULES)})", *where)
            if rule not in RULES:
                fail(f"{k}.rule", f"one of {', '.join(RULES)}", *where)
        if procedure in ("staircase", "weighted-staircase"):
            for key in ("start", "step", "min", "max"):
                if key not in options:
                    fail(f"{k}.{key}", "required: a number", *where)
                if not _number(options[key]):
                    fail(f"{k}.{key}", f"a finite number (got {options[key]!r})", *where)
            if options["step"] <= 0:
                fail(f"{k}.step", f"must be > 0 (got {options['step']:g})", *where)
            if options["min"] >= options["max"]:
                fail(f"{k}.max", f"must be above min ({options['min']:g}; got {options['max']:g})", *where)
            if not options["min"] <= options["start"] <= options["max"]:
                fail(f"{k}.start", f"must be within [min, max] = [{options['min']:g}, {options['max']:g}] "
                     f"(got {options['start']:g})", *where)
            for key, low in (("reversals", 1), ("discard", 0), ("max_trials", 1)):
                if key in options and (not _integer(options[key]) or options[key] < low):
                    fail(f"{k}.{key}", f"an integer >= {low} (got {options[key]!r})", *where)
            if not options.get("discard", 4) < options.get("reversals", 12):
                fail(f"{k}.discard", f"must be below reversals ({options.get('reversals', 12)}): the threshold is the "
                     "mean of the reversals after these", *where)
            if procedure == "weighted-staircase":
                target = options.get("target", 0.75)
                if not _number(target) or not 0.5 < target < 1.0:
                    fail(f"{k}.target", f"a proportion correct above 0.5 (guessing in two intervals) and below 1 "
                         f"(got {target!r})", *where)
        if procedure in ("constant-stimuli", "rating", "paired-comparison", "task"):
            if not _integer(options.get("repetitions")) or options["repetitions"] < 1:
                fail(f"{k}.repetitions", "an integer >= 1", *where)
        if procedure == "constant-stimuli":
            levels = options.get("levels")
            if not isinstance(levels, list) or len(levels) < 3 or any(not _number(x) or x <= 0 for x in levels):
                fail(f"{k}.levels", "at least 3 levels, each a finite number > 0", *where)
            if options.get("form", "weibull") not in ("weibull", "logistic"):
                fail(f"{k}.form", "weibull or logistic", *where)
        elif procedure == "rating":
            named = options.get("conditions")
            if not isinstance(named, list) or len(named) < 2 or any(c not in conditions for c in named):
                fail(f"{k}.conditions", f"two or more conditions' names ({', '.join(conditions)})", *where)
            items = options.get("items")
            if not isinstance(items, list) or not items:
                fail(f"{k}.items", "at least one item: {name, scale, points, anchors}", *where)
            seen = set()
            for j, item in enumerate(items):
                ok = (isinstance(item, dict) and set(item) <= {"name", "scale", "points", "anchors"}
                      and isinstance(item.get("name"), str) and item["name"] and item.get("scale") in SCALES
                      and _integer(item.get("points")) and 3 <= item["points"] <= 11 and item["points"] % 2 == 1
                      and isinstance(item.get("anchors"), list) and len(item["anchors"]) == 2
                      and all(isinstance(a, str) for a in item["anchors"]))
                if not ok:
                    fail(f"{k}.items[{j + 1}]", f"name, scale ({' or '.join(SCALES)}), points (odd, 3 to "
                         "11) and anchors (two words: the scale's ends), and no other key", *where)
                if item["name"] in seen:
                    fail(f"{k}.items[{j + 1}]", f"a second item named '{item['name']}': each item's rating is "
                         "recorded under its name", *where)
                seen.add(item["name"])
        elif procedure == "task":
            named = options.get("conditions")
            if not isinstance(named, list) or not named or any(c not in conditions for c in named):
                fail(f"{k}.conditions", f"one or more conditions' names ({', '.join(conditions)})", *where)
            if options.get("task") not in TASKS:
                fail(f"{k}.task", f"one of {', '.join(TASKS)}", *where)
            if "script" in options:
                if not isinstance(options["script"], str) or not options["script"]:
                    fail(f"{k}.script", "a hand script (a path)", *where)
                options["script"] = os.path.normpath(os.path.join(here, options["script"]))
                if files and not os.path.isfile(options["script"]):
                    fail(f"{k}.script", f"no such file: {options['script']}", *where)
            for key in ("after", "until", "hold", "speed_tolerance", "fall_depth"):
                if key in options and (not _number(options[key]) or options[key] < 0):
                    fail(f"{k}.{key}", f"a finite number >= 0 (got {options[key]!r})", *where)
            if "until" in options and options["until"] <= options.get("after", 0.0):
                fail(f"{k}.until", f"must be after `after` ({options.get('after', 0.0):g} s)", *where)
            for key in ("target", "direction"):
                if key in options and (not isinstance(options[key], list) or len(options[key]) != 3 or any(
                        not _number(x) for x in options[key])):
                    fail(f"{k}.{key}", "three finite numbers [x, y, z] (m; a direction need not be a unit)", *where)
            if "direction" in options and not any(options["direction"]):
                fail(f"{k}.direction", "not [0, 0, 0]: the motion's direction", *where)
        elif procedure == "paired-comparison":
            pairs = options.get("pairs")
            if not isinstance(pairs, list) or not pairs or any(
                    not isinstance(p, list) or len(p) != 2 or p[0] == p[1] or any(c not in conditions for c in p)
                    for p in pairs):
                fail(f"{k}.pairs", f"pairs of two different conditions ({', '.join(conditions)})", *where)
            if "question" not in options:
                fail(f"{k}.question", "required: the question asked after each pair", *where)
        blocks.append(Block(name, procedure, b.get("reference", ""), b.get("test", ""), options))
    if not blocks:
        fail("block", "at least one [[block]]")
    exp = Experiment(path, text, data["name"], seed, order, script, quantity, conditions, blocks,
                     instructions=instructions)
    if files:
        if device not in DEVICES:
            raise ValueError(f"device '{device}': one of {', '.join(DEVICES)}")
        _check_files(exp, fail, lines, device)
    return exp


def _check_files(exp: Experiment, fail, lines: Dict[str, int], device: str) -> None:
    """Loads every scene (as each condition sets it: overrides, and each level a block can give
    its `vary` key) and hand script as a session on `device` would, and checks that the
    conditions the blocks present share one list of effects and one [device] table: a run on a
    device starts with one scene and takes the others as live changes, which may not alter them
    (docs/spec/control-protocol.md)."""
    from toonforce import _toonforce

    from .session import scene_with

    checked = "falcon" if device == "sim" else device  # the simulated device is a Falcon's model
    exp.files = {}

    def check(where, key, scene_path, text, what=""):
        try:
            report = _toonforce.check(scene_path, text, "", None, checked, 1000.0, "double", False, False)
        except _toonforce.SceneError as e:
            report = {"ok": False, "errors": [e.message]}
        if not report["ok"]:
            first = " ".join(report["errors"][0].strip().splitlines()[:3])
            fail(key, f"{what}does not load on the {checked}: {first}", *where)

    def check_script(where, key, script):
        try:
            _toonforce.script_info(script, None)
        except _toonforce.SceneError as e:
            fail(key, f"the hand script does not load: {' '.join(e.message.strip().splitlines()[:3])}", *where)
        exp.files[script] = file_sha256(script)

    check_script((), "script", exp.script)
    layouts: Dict[str, Any] = {}
    for name, c in exp.conditions.items():
        where, key = ("condition", lines[name]), f"condition[{lines[name] + 1}]"
        check(where, f"{key}.scene", c.scene, None)
        exp.files[c.scene] = file_sha256(c.scene)
        try:
            scene = scene_with(c, None)
        except ValueError as e:
            fail(f"{key}.overrides", str(e), *where)
        try:
            if c.vary:
                scene_with(c, 1.0)  # the effect `vary` names must exist (its levels are checked by block)
        except ValueError as e:
            fail(f"{key}.vary", str(e), *where)
        if c.overrides:
            check(where, f"{key}.overrides", c.scene, _toonforce.toml_from_dict(scene), "the scene with its overrides ")
        info = _toonforce.scene_info(c.scene, _toonforce.toml_from_dict(scene), "double", False)
        effects = list(dict.fromkeys(v.split(".")[0] for v in info["values"]))
        layouts[name] = (effects, scene.get("device", {}))
    for i, b in enumerate(exp.blocks):
        where, k = ("block", i), f"block[{i + 1}]"
        if b.procedure in LEVEL_PROCEDURES:
            c = exp.conditions[b.test]
            if b.procedure == "constant-stimuli":
                levels = [("levels", x) for x in b.options["levels"]]
            else:
                levels = [("min", b.options["min"]), ("max", b.options["max"]), ("start", b.options["start"])]
            for key, level in levels:
                check(where, f"{k}.{key}", c.scene, _toonforce.toml_from_dict(scene_with(c, level)),
                      f"condition '{c.name}' with {c.vary} = {level:g} ")
        if b.procedure == "task" and "script" in b.options:
            check_script(where, f"{k}.script", b.options["script"])
    used = exp.used_conditions()
    first = used[0]
    for i, b in enumerate(exp.blocks):
        key = {"staircase": "test", "weighted-staircase": "test", "constant-stimuli": "test"}.get(
            b.procedure, "pairs" if b.procedure == "paired-comparison" else "conditions")
        for name in b.conditions():
            (effects, device_table), (first_effects, first_device) = layouts[name], layouts[first]
            if effects != first_effects:
                fail(f"block[{i + 1}].{key}", f"condition '{name}' has the effects {', '.join(effects) or 'none'}, "
                     f"condition '{first}' {', '.join(first_effects) or 'none'}: a run on a device keeps its first "
                     "scene's list of effects (the trace's columns), so every condition a session presents needs the "
                     "same list (move an effect out of reach instead of leaving it out)", "block", i)
            if device_table != first_device:
                fail(f"block[{i + 1}].{key}", f"condition '{name}' has another [device] table than condition "
                     f"'{first}': a run on a device keeps its first scene's (the safety limits)", "block", i)


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
