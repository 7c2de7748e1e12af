# SPDX-License-Identifier: Apache-2.0
"""toonforce study: the device silent outside the intervals (measured in the session's run
trace on the simulated device), experiment files checked whole before any session folder is
written (every mistake named by file, line and key), and the session folder that is enough for
the analysis while `resume` refuses changed scenes and hand scripts."""

import csv
import http.client
import json
import math
import os
import re
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

from toonforce.study import experiment as experiments
from toonforce.study.__main__ import main as study_main
from toonforce.study.analysis import analyze
from toonforce.study.session import Session
from toonforce.study.simulated import SimulatedParticipant

SOURCE_DIR = os.environ.get("TOONFORCE_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
SCENES = os.path.join(SOURCE_DIR, "scenes")
# The live-scene update fade (docs/spec/live-scenes.md section 5): a scene change's force
# difference ramps out over 0.25 s.
UPDATE_FADE_S = 0.25


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "toonforce.study", *args], capture_output=True, text=True,
                          env=os.environ.copy(), timeout=600)


# ---- experiment files: every mistake before any folder ----------------------------------

BASE = f"""name = "checked"
order = "fixed"
seed = 4
script = "{SCENES}/hands/stroke.toml"

[[condition]]
name = "floor"
scene = "{SCENES}/studies/floor.toml"

[[condition]]
name = "ice"
scene = "{SCENES}/slippery.toml"
vary = "surface1.slippery.mu"

[[condition]]
name = "friction"
scene = "{SCENES}/realistic_friction.toml"

[[block]]
name = "staircase"
procedure = "staircase"
reference = "floor"
test = "ice"
rule = "1-up-2-down"
start = 4.0
step = 0.25
min = 0.05
max = 10.0
reversals = 6
discard = 2

[[block]]
name = "constant"
procedure = "constant-stimuli"
reference = "floor"
test = "ice"
levels = [0.5, 1.0, 2.0]
repetitions = 1

[[block]]
name = "ratings"
procedure = "rating"
conditions = ["friction", "ice"]
repetitions = 1
items = [{{ name = "slippery", scale = "likert", points = 5, anchors = ["no", "very"] }}]

[[block]]
name = "stop"
procedure = "task"
task = "hold-still"
conditions = ["friction"]
repetitions = 1
after = 1.0
until = 1.35
"""

BAD_SCENE = """[[surface]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
stiffness = -5.0
"""

CLIFF_SCENE = f"""[device]
max_force = 8.0
max_force_rate = 2000.0
velocity_cutoff = 50.0
soft_start = 0.1

[[cliff]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
axis = [1.0, 0.0, 0.0]
gap_min = 0.0
gap_max = 0.02
stiffness = 1500.0
speed_threshold = 0.08
"""

OTHER_DEVICE = open(os.path.join(SCENES, "studies", "floor.toml")).read().replace("max_force = 8.0", "max_force = 6.0")

BAD_HAND = """name = "no segments"
[hand]
start = [0.0, 0.0, 0.01]
"""


def sub(text, old, new, count=1):
    assert old in text, old
    return text.replace(old, new, count)


# (what, how the base file is changed, the line's text the error must name, key, words in the
# message). The line is found by its text in the changed file.
MISTAKES = [
    ("a step that is not a number", lambda t: sub(t, "step = 0.25", "step = nan"), "step = nan", "block[1].step",
     "a finite number"),
    ("an infinite maximum", lambda t: sub(t, "max = 10.0", "max = inf"), "max = inf", "block[1].max",
     "a finite number"),
    ("a negative step", lambda t: sub(t, "step = 0.25", "step = -0.25"), "step = -0.25", "block[1].step",
     "must be > 0"),
    ("a 2-up-1-down rule in 2IFC", lambda t: sub(t, 'rule = "1-up-2-down"', 'rule = "2-up-1-down"'),
     'rule = "2-up-1-down"', "block[1].rule", "below the 50 % of guessing"),
    ("a start outside [min, max]", lambda t: sub(t, "start = 4.0", "start = 12.0"), "start = 12.0", "block[1].start",
     "within [min, max]"),
    ("min above max", lambda t: sub(t, "min = 0.05", "min = 20.0"), "max = 10.0", "block[1].max", "above min"),
    ("discard not below reversals", lambda t: sub(t, "discard = 2", "discard = 6"), "discard = 6", "block[1].discard",
     "below reversals"),
    ("a fractional reversal count", lambda t: sub(t, "reversals = 6", "reversals = 6.5"), "reversals = 6.5",
     "block[1].reversals", "an integer >= 1"),
    ("a level that is not a number", lambda t: sub(t, "levels = [0.5, 1.0, 2.0]", "levels = [0.5, nan, 2.0]"),
     "levels = [0.5, nan, 2.0]", "block[2].levels", "finite number > 0"),
    ("zero repetitions", lambda t: sub(t, "repetitions = 1", "repetitions = 0", 2).replace(
        "repetitions = 0", "repetitions = 1", 1), "repetitions = 0", "block[3].repetitions", "an integer >= 1"),
    ("a level the scene refuses (mu = 0 at the staircase's min)", lambda t: sub(t, "min = 0.05", "min = 0.0"),
     "min = 0.0", "block[1].min", "surface[1].slippery.mu: must be > 0"),
    ("a vary key the scene does not have", lambda t: sub(t, 'vary = "surface1.slippery.mu"',
                                                          'vary = "surface1.slippery.muu"'),
     "min = 0.05", "block[1].min", "unknown key 'muu'"),
    ("a vary effect the scene does not have", lambda t: sub(t, 'vary = "surface1.slippery.mu"',
                                                             'vary = "surface2.slippery.mu"'),
     'vary = "surface2.slippery.mu"', "condition[2].vary", "no effect surface2"),
    ("an override the scene refuses", lambda t: sub(t, 'scene = "' + SCENES + '/realistic_friction.toml"',
                                                    'scene = "' + SCENES + '/realistic_friction.toml"\n'
                                                    'overrides = { "surface1.stiffness" = -1.0 }'),
     'overrides = { "surface1.stiffness" = -1.0 }', "condition[3].overrides", "stiffness: must be > 0"),
    ("a scene that does not load", lambda t: sub(t, SCENES + "/realistic_friction.toml", "BAD_SCENE"),
     'scene = "BAD_SCENE"', "condition[3].scene", "stiffness: must be > 0"),
    ("conditions with different effect lists in a block",
     lambda t: sub(t, SCENES + "/realistic_friction.toml", "CLIFF_SCENE"), 'conditions = ["friction", "ice"]',
     "block[3].conditions", "a run on a device keeps its first scene's list of effects"),
    ("conditions with different [device] tables", lambda t: sub(t, SCENES + "/realistic_friction.toml",
                                                                "OTHER_DEVICE"),
     'conditions = ["friction", "ice"]', "block[3].conditions", "another [device] table"),
    ("a hand script that does not load", lambda t: sub(t, SCENES + "/hands/stroke.toml", "BAD_HAND"),
     'script = "BAD_HAND"', "script", "the hand script does not load"),
    ("a task's number that is not a number", lambda t: sub(t, "after = 1.0", "after = nan"), "after = nan",
     "block[4].after", "a finite number >= 0"),
    ("a task window that ends before it starts", lambda t: sub(t, "until = 1.35", "until = 0.5"), "until = 0.5",
     "block[4].until", "must be after `after`"),
    ("a weighted staircase's target at chance", lambda t: sub(t, 'procedure = "staircase"\nreference = "floor"\n'
                                                              'test = "ice"\nrule = "1-up-2-down"',
                                                              'procedure = "weighted-staircase"\nreference = "floor"\n'
                                                              'test = "ice"\ntarget = 0.5'),
     "target = 0.5", "block[1].target", "above 0.5"),
    ("a test condition that is the reference", lambda t: sub(t, 'reference = "floor"\ntest = "ice"\nlevels',
                                                             'reference = "ice"\ntest = "ice"\nlevels'),
     'test = "ice"\nlevels', "block[2].test", "must differ from the reference"),
    ("two rating items of one name", lambda t: sub(t, 'anchors = ["no", "very"] }]', 'anchors = ["no", "very"] }, '
                                                   '{ name = "slippery", scale = "likert", points = 5, '
                                                   'anchors = ["a", "b"] }]'),
     "items = [", "block[3].items[2]", "a second item named 'slippery'"),
    ("a seed that is a boolean", lambda t: sub(t, "seed = 4", "seed = true"), "seed = true", "seed",
     "a non-negative integer"),
    ("a vary key that is not an effect's key", lambda t: sub(t, 'vary = "surface1.slippery.mu"', 'vary = "mu"'),
     'vary = "mu"', "condition[2].vary", "an effect's key"),
    # What the participant's page says (docs/STUDIES.md, "A person at a device").
    ("one answer label for two intervals", lambda t: sub(t, "discard = 2", 'discard = 2\nanswers = ["this one"]'),
     'answers = ["this one"]', "block[1].answers", "two different texts"),
    ("two answer labels alike", lambda t: sub(t, "levels = [0.5, 1.0, 2.0]",
                                              'levels = [0.5, 1.0, 2.0]\nanswers = ["one", "one"]'),
     'answers = ["one", "one"]', "block[2].answers", "two different texts"),
    ("an empty question", lambda t: sub(t, 'conditions = ["friction", "ice"]\n',
                                        'conditions = ["friction", "ice"]\nquestion = " "\n'),
     'question = " "', "block[3].question", "text shown to the participant"),
    ("instructions that are not text", lambda t: sub(t, 'task = "hold-still"', 'task = "hold-still"\ninstructions = 3'),
     "instructions = 3", "block[4].instructions", "text shown to the participant"),
    ("a question on a task", lambda t: sub(t, 'task = "hold-still"', 'task = "hold-still"\nquestion = "Well?"'),
     'question = "Well?"', "block[4].question", "a task asks nothing"),
    ("answer labels on a rating", lambda t: sub(t, 'conditions = ["friction", "ice"]\n',
                                                'conditions = ["friction", "ice"]\nanswers = ["a", "b"]\n'),
     'answers = ["a", "b"]', "block[3].answers", "its items' points"),
    ("start instructions that are not text", lambda t: sub(t, "seed = 4", "seed = 4\ninstructions = false"),
     "instructions = false", "instructions", "before the participant presses Start"),
]


def write_mistake(tmp_path, change):
    (tmp_path / "bad_scene.toml").write_text(BAD_SCENE)
    (tmp_path / "cliff.toml").write_text(CLIFF_SCENE)
    (tmp_path / "other_device.toml").write_text(OTHER_DEVICE)
    (tmp_path / "bad_hand.toml").write_text(BAD_HAND)
    text = change(BASE)
    for name, file in (("BAD_SCENE", "bad_scene.toml"), ("CLIFF_SCENE", "cliff.toml"),
                       ("OTHER_DEVICE", "other_device.toml"), ("BAD_HAND", "bad_hand.toml")):
        text = text.replace(f'"{name}"', f'"{file}"')
    path = tmp_path / "study.toml"
    path.write_text(text)
    return path, text


def test_the_base_experiment_passes(tmp_path):
    path, _ = write_mistake(tmp_path, lambda t: t)
    done = run_cli("check", str(path))
    assert done.returncode == 0, done.stderr
    assert "ok on the sim device" in done.stdout
    assert experiments.file_sha256(os.path.join(SCENES, "slippery.toml")) in done.stdout


@pytest.mark.parametrize("what,change,line_text,key,words", MISTAKES, ids=[m[0] for m in MISTAKES])
def test_a_mistake_is_named_by_file_line_and_key_before_any_folder(tmp_path, capsys, what, change, line_text, key,
                                                                   words):
    path, text = write_mistake(tmp_path, change)
    line_text = line_text.replace("BAD_SCENE", "bad_scene.toml").replace("BAD_HAND", "bad_hand.toml")
    line = text[:text.index(line_text)].count("\n") + 1
    expected = f"{path}:{line}: {key}: "
    folder = tmp_path / "session"
    for device in (["--simulated-threshold", "1.2"], ["--device", "sim", "--allow-non-rt"]):
        try:
            status = study_main(["run", str(path), "--participant", "1", "--out", str(folder), *device])
        except Exception as e:  # noqa: BLE001 - a mistake found late: the test fails below
            status = repr(e)
        said = capsys.readouterr().err
        assert not folder.exists(), f"{what}: a folder was written ({status}: {said})"
        assert status == 2 and expected in said and words in said, (what, status, said)
    assert study_main(["check", str(path)]) == 2, what
    said = capsys.readouterr().err
    assert expected in said and words in said, (what, expected, words, said)


def test_every_block_says_what_its_file_says_or_the_default():
    """The page's words (person.py asks them of experiment.page_text): the file's on every kind
    of block that has them, the defaults elsewhere."""
    words = {"instructions": "Feel it.", "question": "Which one?", "answers": ["this", "that"]}
    said = "".join(f"{k} = {json.dumps(v)}\n" for k, v in words.items())
    text = BASE.replace("discard = 2\n", "discard = 2\n" + said)  # the staircase
    text = text.replace("levels = [0.5, 1.0, 2.0]\n", "levels = [0.5, 1.0, 2.0]\n" + said)  # constant stimuli
    text = text.replace('conditions = ["friction", "ice"]\n', 'conditions = ["friction", "ice"]\n'
                        'instructions = "Explore."\nquestion = "How?"\n')  # the rating
    text = text.replace('task = "hold-still"', 'task = "hold-still"\ninstructions = "Stop there."')
    text += ('\n[[block]]\nprocedure = "paired-comparison"\npairs = [["friction", "ice"]]\nrepetitions = 1\n'
             'question = "Which was more slippery?"\n')
    text = 'instructions = "Welcome."\n' + text
    exp = experiments.load(os.path.join(SCENES, "studies", "here.toml"), text, files=False)
    assert exp.instructions == "Welcome."
    staircase, constant, rating, task, paired = exp.blocks
    for block in (staircase, constant):
        assert {k: experiments.page_text(block, k) for k in words} == words
    assert (experiments.page_text(rating, "instructions"), experiments.page_text(rating, "question")) == (
        "Explore.", "How?")
    assert experiments.page_text(task, "instructions") == "Stop there."
    assert experiments.page_text(paired, "question") == "Which was more slippery?"
    assert experiments.page_text(paired, "answers") == ["the first", "the second"]
    assert experiments.page_text(paired, "instructions") == "Stroke across the surface."
    plain = experiments.load(os.path.join(SCENES, "studies", "here.toml"), BASE, files=False)
    assert plain.instructions == experiments.START_TEXT
    assert experiments.page_text(plain.blocks[0], "question") == "Which interval pushed your hand along?"
    assert experiments.page_text(plain.blocks[2], "question") == "How was it?"
    assert experiments.page_text(plain.blocks[3], "instructions") == ""


def test_a_session_folder_keeps_the_experiment_and_the_hashes_and_is_analysed_alone(tmp_path):
    source = tmp_path / "files"
    source.mkdir()
    scene = source / "floor.toml"
    scene.write_text(open(os.path.join(SCENES, "studies", "floor.toml")).read())
    text = BASE.replace(f"{SCENES}/studies/floor.toml", str(scene))
    path = source / "study.toml"
    path.write_text(text)
    session = Session.start(str(path), str(tmp_path / "s"), participant=1, seed=1)
    exp = session.experiment
    session.run(SimulatedParticipant.with_threshold(exp, exp.blocks[1], 1.2, seed=1))
    assert session.done
    meta = json.load(open(tmp_path / "s" / "session.json"))
    assert meta["experiment_text"] == text
    files = meta["files"]
    assert files[str(scene)] == experiments.file_sha256(str(scene))
    assert set(files) == {str(scene), os.path.join(SCENES, "slippery.toml"),
                          os.path.join(SCENES, "realistic_friction.toml"), os.path.join(SCENES, "hands", "stroke.toml")}
    # The experiment file and its scene moved away (edited, then deleted): the folder alone is
    # enough to read the session as it was.
    path.write_text(text.replace("repetitions = 1", "repetitions = 2"))
    os.rename(path, tmp_path / "elsewhere.toml")
    os.rename(scene, tmp_path / "floor_elsewhere.toml")
    opened = Session(session.folder)
    assert opened.experiment.text == text and [b.name for b in opened.experiment.blocks] == [
        "staircase", "constant", "ratings", "stop"]
    assert opened.experiment.blocks[1].options["repetitions"] == 1
    report = open(analyze([session.folder], str(tmp_path / "report"))).read()
    assert "constant" in report and "ratings" in report
    with pytest.raises(ValueError, match="not there any more"):
        Session(session.folder, resume=True)


def test_resume_refuses_a_changed_scene_or_hand_script_naming_it_and_both_hashes(tmp_path):
    scene = tmp_path / "slippery.toml"
    scene.write_text(open(os.path.join(SCENES, "slippery.toml")).read())
    hand = tmp_path / "stroke.toml"
    hand.write_text(open(os.path.join(SCENES, "hands", "stroke.toml")).read())
    path = tmp_path / "study.toml"
    path.write_text(BASE.replace(f"{SCENES}/slippery.toml", str(scene)).replace(
        f"{SCENES}/hands/stroke.toml", str(hand)))
    session = Session.start(str(path), str(tmp_path / "s"), participant=1, seed=1)
    Session(session.folder, resume=True)  # unchanged: it opens
    for file, old, new in ((scene, "stiffness = 1500.0", "stiffness = 1400.0"),
                           (hand, "stiffness = 100.0", "stiffness = 90.0")):
        original = file.read_text()
        recorded = experiments.file_sha256(str(file))
        file.write_text(original.replace(old, new))
        now = experiments.file_sha256(str(file))
        with pytest.raises(ValueError) as e:
            Session(session.folder, resume=True)
        assert str(file) in str(e.value) and recorded in str(e.value) and now in str(e.value), str(e.value)
        resumed = run_cli("resume", session.folder)
        assert resumed.returncode == 2 and f"{file} changed since the session started" in resumed.stderr
        file.write_text(original)
    Session(session.folder, resume=True)


def test_a_sessions_hand_script_is_recorded_and_resume_keeps_it(tmp_path):
    hand = tmp_path / "press.toml"
    hand.write_text(open(os.path.join(SCENES, "hands", "stroke.toml")).read())
    path = tmp_path / "study.toml"
    path.write_text(BASE)
    session = Session.start(str(path), str(tmp_path / "s"), participant=1, seed=1, hand=str(hand))
    recorded = experiments.file_sha256(str(hand))
    assert session.meta["hand"] == str(hand) and session.meta["files"][str(hand)] == recorded
    Session(session.folder, resume=True, hand=str(hand))  # the same hand, unchanged: it opens
    with pytest.raises(ValueError, match="began with --hand"):
        Session(session.folder, resume=True)
    other = tmp_path / "other.toml"
    other.write_text(hand.read_text())
    with pytest.raises(ValueError, match="began with --hand"):
        Session(session.folder, resume=True, hand=str(other))
    original = hand.read_text()
    hand.write_text(original.replace("stiffness = 100.0", "stiffness = 90.0"))
    with pytest.raises(ValueError) as e:
        Session(session.folder, resume=True, hand=str(hand))
    assert str(hand) in str(e.value) and recorded in str(e.value), str(e.value)
    resumed = run_cli("resume", session.folder, "--hand", str(hand))
    assert resumed.returncode == 2 and f"{hand} changed since the session started" in resumed.stderr
    hand.write_text(original)
    # A session begun without --hand is not resumed with one.
    plain = Session.start(str(path), str(tmp_path / "p"), participant=1, seed=1)
    with pytest.raises(ValueError, match="began without --hand"):
        Session(plain.folder, resume=True, hand=str(hand))
    # A simulated participant has no hand on the device: --hand is refused, and no folder written.
    refused = run_cli("run", str(path), "--participant", "1", "--out", str(tmp_path / "o"),
                      "--simulated-threshold", "0.2", "--hand", str(hand))
    assert refused.returncode == 2 and "--hand" in refused.stderr and not (tmp_path / "o").exists()


# ---- the device silent between intervals ------------------------------------------------

SILENCE_EXPERIMENT = f"""
name = "silence"
order = "fixed"
seed = 3
script = "{SCENES}/hands/stroke.toml"

[[condition]]
name = "floor"
scene = "floor.toml"

[[condition]]
name = "ice"
scene = "slippery.toml"
vary = "surface1.slippery.mu"

[[block]]
name = "levels"
procedure = "constant-stimuli"
reference = "floor"
test = "ice"
levels = [2.0, 4.0, 8.0]
repetitions = 1
"""


def pressing_hand():
    """A hand that lowers onto the floor and strokes back and forth along x at 0.1 m/s pressing
    with 1 N, for longer than the session: a surface left on pushes it all the time."""
    segments = ['[[segment]]\ntype = "move"\nto = [-0.03, 0.0, 0.0]\nduration = 0.2\n',
                '[[segment]]\ntype = "hold"\nduration = 0.2\nforce = 1.0\n']
    for k in range(40):
        x = 0.03 if k % 2 == 0 else -0.03
        segments.append(f'[[segment]]\ntype = "stroke"\nto = [{x}, 0.0, 0.0]\nspeed = 0.1\nforce = 1.0\n')
    return ('name = "pressing strokes"\n[hand]\nstart = [-0.03, 0.0, 0.003]\nstiffness = 100.0\n\n'
            + "\n".join(segments))


def get(url):
    with urllib.request.urlopen(url, timeout=5) as r:
        return json.loads(r.read())


def post(url, body):
    request = urllib.request.Request(url, data=json.dumps(body).encode(), method="POST")
    with urllib.request.urlopen(request, timeout=5) as r:
        return r.read()


def play_slowly(process, url, think_s):
    """Answers each question `think_s` after it appears (the participant thinks: the window the
    force must be silent in), always "the second"."""
    seen = None
    while process.poll() is None:
        try:
            state = get(url + "state")
            if state["phase"] == "start":  # the session waits for the participant's Start
                post(url + "answer", {"token": state["token"], "value": "start"})
            elif state["phase"] == "choice" and state["token"] != seen:
                seen = state["token"]
                time.sleep(think_s)
                post(url + "answer", {"token": state["token"], "value": 2})
        except (OSError, http.client.HTTPException):  # the page ends with the session
            time.sleep(0.02)
        time.sleep(0.01)


def read_trace(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    columns = {k: np.array([float(r[k]) if r[k] != "" else np.nan for r in rows])
               for k in ("t", "fx", "fy", "fz", "latched", "surface1.contact")}
    columns["force"] = np.sqrt(columns["fx"] ** 2 + columns["fy"] ** 2 + columns["fz"] ** 2)
    return columns


@pytest.mark.skipif(os.environ.get("TOONFORCE_VIEWER", "1") in ("0", "OFF"),
                    reason="needs `toonforce run --control` (a build with the viewer)")
def test_the_device_is_silent_between_intervals_during_the_blank_and_the_question(tmp_path):
    experiment = tmp_path / "silence.toml"
    experiment.write_text(SILENCE_EXPERIMENT)
    # The example's scenes, with a watchdog that tolerates a busy test machine's stalls (the run
    # is not real-time here): a latched missed-tick fault would silence the device for good.
    for name, source in (("floor.toml", "studies/floor.toml"), ("slippery.toml", "slippery.toml")):
        text = open(os.path.join(SCENES, source)).read()
        (tmp_path / name).write_text(text.replace("[device]\n", "[device]\nwatchdog_periods = 5000\n"))
    hand = tmp_path / "hand.toml"
    hand.write_text(pressing_hand())
    folder = tmp_path / "session"
    process = subprocess.Popen([sys.executable, "-m", "toonforce.study", "run", str(experiment), "--participant", "1",
                                "--out", str(folder), "--device", "sim", "--hand", str(hand), "--allow-non-rt",
                                "--interval", "0.6"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                               env=os.environ.copy())
    url, seen = None, []
    while url is None:
        line = process.stderr.readline()
        assert line, "".join(seen)
        seen.append(line)
        m = re.search(r"page: (http://\S+/)", line)
        url = m.group(1) if m else None
    think_s = 0.6
    play_slowly(process, url, think_s)
    _, errors = process.communicate(timeout=120)
    assert process.returncode == 0, errors
    trials = [json.loads(line) for line in open(folder / "trials.jsonl")]
    assert len(trials) == 3
    trace = read_trace(folder / "run-1.csv")
    rate_hz = 1.0 / float(np.median(np.diff(trace["t"])))
    force = trace["force"]
    assert np.all(np.array([float(r) for r in trace["latched"]]) == 0), "a latched fault: the device went silent"
    # Every blank, across trials too. The silent scene's plane is out of reach, so the first
    # frame at or after `off` without contact is the tick that applied it (the recorded frame
    # counts lag the loop). From there the force fades (the difference it started with ramps
    # out; what the handle does moves it by a few hundredths of a newton), and it is zero from
    # the fade's end to the next interval's start.
    intervals = [i for t in trials for i in t["trace"]["intervals"]]
    assert len(intervals) == 6
    fade = int(round(UPDATE_FADE_S * rate_hz))
    # The scene acts in every interval: the pressing hand feels the floor's push (about its 1 N
    # press), so the silence around them is the scene switched off, not a hand in the air.
    for on, off in intervals:
        assert np.median(force[on + fade + 100:off]) > 0.7, (on, off, np.median(force[on + fade + 100:off]))
    silent_spans = []
    for (on, off), (next_on, _) in zip(intervals, intervals[1:] + [(len(force), None)]):
        switched = off + int(np.argmax(trace["surface1.contact"][off:] == 0))
        assert trace["surface1.contact"][switched] == 0 and switched - off < 0.2 * rate_hz, (off, switched)
        assert force[switched:switched + fade].max() <= force[switched - 1] + 0.1, "the fade pushed harder"
        silent = force[switched + fade + 5:next_on]
        assert next_on - (switched + fade) > 0.1 * rate_hz, "a blank shorter than the fade"
        assert silent.max() < 1e-6, f"frames {switched + fade + 5}..{next_on}: up to {silent.max():.3f} N silent"
        silent_spans.append((switched + fade + 5, next_on))
    # The question lies in those silent spans: each trial is answered (its last frame) after its
    # last interval's fade and before the next interval. Its start is not taken from the answer's
    # response time: on a loaded machine the loop and its telemetry lag the wall clock, and
    # frames counted back from the answer at the nominal rate reached into the interval.
    for t in trials:
        _, end = t["trace"]["frames"]
        assert any(start <= end <= stop for start, stop in silent_spans), (t["trial"], end, silent_spans)


def test_the_silent_scene_keeps_the_effects_and_moves_them_out_of_reach():
    from toonforce import _toonforce
    from toonforce.study.person import silent_scene
    import tomllib

    cliff = tomllib.loads(CLIFF_SCENE)
    cliff["cliff"][0]["fall_force"] = 2.0
    quiet = silent_scene(cliff)
    assert quiet["cliff"][0]["point"] == [0.0, 0.0, -1.0] and quiet["cliff"][0]["fall_force"] == 0.0
    assert quiet["device"] == cliff["device"]
    info = _toonforce.scene_info("quiet", _toonforce.toml_from_dict(quiet), "double", False)
    assert info["values"] == _toonforce.scene_info("cliff", _toonforce.toml_from_dict(cliff), "double", False)["values"]
    slanted = {"surface": [{"point": [0.01, 0.0, 0.0], "normal": [0.0, 3.0, 4.0], "stiffness": 100.0}]}
    moved = silent_scene(slanted)["surface"][0]["point"]
    assert np.allclose(moved, [0.01, -0.6, -0.8])
    assert math.isclose(np.linalg.norm(np.subtract(moved, [0.01, 0, 0])), 1.0)
