# SPDX-License-Identifier: Apache-2.0
"""A study session: one folder, nothing lost.

    FOLDER/session.json   the experiment file's text and SHA-256, the SHA-256 of every scene
                          and hand script it names, the participant, the seed, the software's
                          version, the device, the block order, the start time
    FOLDER/trials.jsonl   one line per trial, appended, flushed and fsync'ed before the next
                          trial starts
    FOLDER/done.json      written once the last block ends

A crash, a power cut or Ctrl-C loses at most the trial in progress (a cut last line is
dropped when the session is opened again), and `resume` goes on from the next trial: the block
order, each procedure's state (rebuilt by replaying the recorded answers) and the order of
constant stimuli all come from the recorded seed.
"""

from __future__ import annotations

import datetime
import json
import os
import random
import secrets
import tomllib
from typing import Any, Callable, Dict, List, Optional

from . import experiment as experiments
from .procedures import (ConstantStimuli, FixedTrials, TransformedStaircase, WeightedStaircase, pair_trials,
                         rating_trials)


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="milliseconds")


def _write_whole(path: str, data: Dict[str, Any]) -> None:
    staged = path + ".staged"
    with open(staged, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=2)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(staged, path)


def make_procedure(block: experiments.Block, seed: int, index: int):
    o = block.options
    if block.procedure in ("rating", "task"):
        return FixedTrials(rating_trials(o["conditions"], o["repetitions"]), seed=seed * 1000 + index)
    if block.procedure == "paired-comparison":
        return FixedTrials(pair_trials(o["pairs"], o["repetitions"]), seed=seed * 1000 + index)
    if block.procedure == "constant-stimuli":
        return ConstantStimuli(o["levels"], o["repetitions"], seed=seed * 1000 + index)
    common = dict(start=float(o["start"]), step=float(o["step"]), minimum=float(o["min"]), maximum=float(o["max"]),
                  reversals=int(o.get("reversals", 12)), discard=int(o.get("discard", 4)),
                  max_trials=int(o.get("max_trials", 200)))
    if block.procedure == "weighted-staircase":
        return WeightedStaircase(**common, target=float(o.get("target", 0.75)))
    up, down = experiments.RULES[o.get("rule", "1-up-2-down")]
    return TransformedStaircase(**common, up=up, down=down)


def scene_with(condition: experiments.Condition, level: Optional[float]) -> Dict[str, Any]:
    """The condition's scene as a dict, its overrides and the level (at `vary`) set."""
    with open(condition.scene, "rb") as f:
        scene = tomllib.load(f)
    settings = dict(condition.overrides)
    if level is not None:
        settings[condition.vary] = level
    for path, value in settings.items():
        effect, *keys = path.split(".")
        kind = effect.rstrip("0123456789")
        number = int(effect[len(kind):] or 0)
        # A scene file's arrays of tables are its effects, one per kind (the loader refuses any
        # other), so no list of the kinds is kept here.
        effects = scene.get(kind)
        if not isinstance(effects, list) or number < 1 or number > len(effects):
            raise ValueError(f"{condition.name}: '{path}': no effect {effect} in {condition.scene}")
        table = effects[number - 1]
        for key in keys[:-1]:
            table = table.setdefault(key, {})
        table[keys[-1]] = value
    return scene


class Session:
    """A session's folder. Opened as it is (`resume=False`), the experiment is the copy of its text
    kept in session.json, its paths taken as they were: the analysis needs nothing outside the
    folder. Opened to resume, the experiment file, every scene and every hand script must be
    where they were and as they were (the same SHA-256), or it refuses, naming what changed."""

    def __init__(self, folder: str, resume: bool = False, hand: Optional[str] = None):
        """`hand`: to resume, the --hand script given now; it must be the one the session began
        with (or none if it began without), as it was."""
        self.folder = os.path.abspath(folder)
        with open(os.path.join(self.folder, "session.json"), encoding="utf-8") as f:
            self.meta: Dict[str, Any] = json.load(f)
        if resume:
            self._same_hand(hand)
            self.experiment = self._unchanged()
        else:
            self.experiment = experiments.load(self.meta["experiment_file"], self.meta["experiment_text"], files=False)
        self.trials: List[Dict[str, Any]] = self._read_trials()

    def _same_hand(self, hand: Optional[str]) -> None:
        """The simulated hand of a session tried without a device (--hand) is part of what the
        participant felt: a resumed session keeps it (its SHA-256 is among the files checked)."""
        recorded = self.meta.get("hand")
        given = os.path.abspath(hand) if hand else None
        if given == recorded:
            return
        if recorded is None:
            raise ValueError(f"--hand {hand}: the session began without --hand; resume it without one")
        if given is None:
            raise ValueError(f"the session began with --hand {recorded}; resume it with the same --hand")
        raise ValueError(f"--hand {hand}: the session began with --hand {recorded}; resume it with that one")

    def _unchanged(self) -> experiments.Experiment:
        """The experiment from its file, with its scenes and hand scripts, as the session began."""
        path = self.meta["experiment_file"]
        if not os.path.isfile(path):
            raise ValueError(f"{path}: the session's experiment file is not there any more (moved or deleted): "
                             "restore it to resume (the analysis needs only the session's folder)")
        now = experiments.file_sha256(path)
        if now != self.meta["experiment_sha256"]:
            raise ValueError(f"{path} changed since the session started (SHA-256 {now[:12]}..., recorded "
                             f"{self.meta['experiment_sha256'][:12]}...): restore it to resume")
        for file, recorded in self.meta.get("files", {}).items():
            if not os.path.isfile(file):
                raise ValueError(f"{file}: a scene or hand script of the session is not there any more (SHA-256 "
                                 f"recorded {recorded}): restore it to resume")
            now = experiments.file_sha256(file)
            if now != recorded:
                raise ValueError(f"{file} changed since the session started (SHA-256 recorded {recorded}, now {now}): "
                                 "a resumed session would present other stimuli; restore it to resume")
        return experiments.load(path, device=self.meta.get("device", "sim"))

    # ---- starting and opening ----------------------------------------------------------

    @staticmethod
    def start(experiment_file: str, folder: str, participant: int, seed: Optional[int] = None,
              device: str = "sim", observer: Optional[Dict[str, Any]] = None, version: str = "",
              hand: Optional[str] = None) -> "Session":
        """Checks the experiment file with every scene and hand script on `device` first: a
        mistake writes no folder. `hand`: the --hand script of a session tried without a device,
        recorded with its SHA-256 like the experiment's own files."""
        if os.path.exists(os.path.join(folder, "session.json")):
            raise FileExistsError(f"{folder} holds a session already: `resume` it, or choose another folder")
        exp = experiments.load(experiment_file, device=device)
        os.makedirs(folder, exist_ok=True)
        seed = seed if seed is not None else (exp.seed if exp.seed is not None else secrets.randbits(31))
        files = dict(exp.files)
        if hand:
            hand = os.path.abspath(hand)
            files[hand] = experiments.file_sha256(hand)
        meta = {
            "experiment_file": exp.path, "experiment_sha256": exp.sha256, "experiment_text": exp.text,
            "files": files,  # every scene and hand script: its SHA-256, compared on resume
            "hand": hand or None,
            "experiment": exp.name, "participant": participant, "seed": seed, "device": device,
            "observer": observer, "version": version, "started_utc": _now(),
            "block_order": exp.block_order(participant, seed),
        }
        _write_whole(os.path.join(folder, "session.json"), meta)
        open(os.path.join(folder, "trials.jsonl"), "a").close()
        return Session(folder)

    def _read_trials(self) -> List[Dict[str, Any]]:
        path = os.path.join(self.folder, "trials.jsonl")
        with open(path, "rb") as f:
            data = f.read()
        whole = data[:data.rfind(b"\n") + 1]
        if len(whole) != len(data):  # the trial in progress when it stopped: not recorded
            with open(path, "r+b") as f:
                f.truncate(len(whole))
                os.fsync(f.fileno())
        return [json.loads(line) for line in whole.decode("utf-8").splitlines() if line.strip()]

    @property
    def done(self) -> bool:
        return os.path.exists(os.path.join(self.folder, "done.json"))

    # ---- running ------------------------------------------------------------------------

    def procedures(self):
        """Each block's procedure with the recorded answers replayed, in the session's order."""
        seed = self.meta["seed"]
        out = []
        for position, index in enumerate(self.meta["block_order"]):
            procedure = make_procedure(self.experiment.blocks[index], seed, index)
            for t in self.trials:
                if t["block"] != index:
                    continue
                if isinstance(procedure, FixedTrials):
                    procedure.record({k: t[k] for k in ("ratings", "chose", "metrics") if k in t})
                    continue
                if procedure.next_level() != t["level"]:
                    raise ValueError(f"trials.jsonl: block {index} trial {t['trial']}: level {t['level']} is not "
                                     f"what the procedure gives ({procedure.next_level()}): a changed file?")
                procedure.record(t["correct"])
            out.append((position, index, procedure))
        return out

    def run(self, participant, progress: Callable[[str], None] = lambda line: None,
            stop_after: Optional[int] = None, before_trial: Callable[[], None] = lambda: None) -> None:
        """Runs the trials left with `participant` (two_interval, rate, compare, perform: a
        SimulatedParticipant or a PersonAtDevice), each trial on disk before the next starts.
        `stop_after`: end after that many new trials; `before_trial`: called before each (the
        experimenter's pause waits there), then the participant's `prepare(block, index)` if it
        has one. Each record has the trial's start (`started_utc`, after those) and its end (`utc`)."""
        seed = self.meta["seed"]
        done_now = 0
        path = os.path.join(self.folder, "trials.jsonl")
        blocks = self.procedures()
        for position, index, procedure in blocks:
            block = self.experiment.blocks[index]
            while not procedure.done:
                if stop_after is not None and done_now >= stop_after:
                    return
                before_trial()
                if hasattr(participant, "prepare"):  # a person: Start, a pause, the break before a block
                    participant.prepare(block, index)
                trial = len(procedure.answers)
                record: Dict[str, Any] = {"block": index, "position": position, "trial": trial,
                                          "procedure": block.procedure, "started_utc": _now()}
                if isinstance(procedure, FixedTrials):
                    spec = procedure.next_trial()
                    if block.procedure == "rating":
                        result = participant.rate(block, index, trial, spec["condition"])
                    elif block.procedure == "task":
                        result = participant.perform(block, index, trial, spec["condition"])
                    else:
                        result = participant.compare(block, index, trial, spec["first"], spec["second"])
                    record.update(spec)
                    said = ", ".join(f"{k} {v}" for k, v in result.get("ratings", {}).items()) or (
                        f"chose {result['chose']}" if "chose" in result else
                        ("success" if result["metrics"].get("success") else "no success"))
                else:
                    level = procedure.next_level()
                    test_first = random.Random(f"{seed}/order/{index}/{trial}").random() < 0.5
                    result = participant.two_interval(block, index, trial, level, test_first)
                    record.update(reference=block.reference, test=block.test, level=level, test_first=test_first)
                    said = f"level {level:g}, {'correct' if result['correct'] else 'wrong'}"
                record.update(result)
                record["utc"] = _now()
                with open(path, "a", encoding="utf-8") as f:
                    f.write(json.dumps(record) + "\n")
                    f.flush()
                    os.fsync(f.fileno())
                procedure.record(result if isinstance(procedure, FixedTrials) else bool(result["correct"]))
                self.trials.append(record)
                done_now += 1
                progress(f"block {position + 1} of {len(blocks)} ({block.name}): trial {trial + 1}: {said}")
        _write_whole(os.path.join(self.folder, "done.json"), {"ended_utc": _now(), "trials": len(self.trials)})


def planned_trials(session: "Session") -> int:
    """The session's trials at most: each fixed block's count, each staircase's max_trials."""
    total = 0
    for _, index, procedure in session.procedures():
        if hasattr(procedure, "_order"):
            total += len(procedure._order)
        else:
            total += procedure.max_trials
    return total
