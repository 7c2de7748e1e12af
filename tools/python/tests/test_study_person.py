# SPDX-License-Identifier: Apache-2.0
"""toonforce study with a person: the participant's page and the device's run, on the
simulated device with a scripted hand, the person played by this test through the page's own
requests. The abort key must end the run on a zero-force tick and keep every answered trial;
resume must go on to the end."""

import csv
import json
import os
import re
import subprocess
import sys
import time
import urllib.request

SOURCE_DIR = os.environ.get("TOONFORCE_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
SCENES = os.path.join(SOURCE_DIR, "scenes")

EXPERIMENT = f"""
name = "a short session"
order = "fixed"
seed = 5
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
name = "levels"
procedure = "constant-stimuli"
reference = "floor"
test = "ice"
levels = [1.0, 2.0, 4.0]
repetitions = 1

[[block]]
name = "ratings"
procedure = "rating"
conditions = ["friction", "ice"]
repetitions = 1
items = [{{ name = "slippery", scale = "likert", points = 5, anchors = ["no", "very"] }}]
"""


def get(url):
    with urllib.request.urlopen(url, timeout=5) as r:
        return json.loads(r.read())


def post(url, body):
    request = urllib.request.Request(url, data=json.dumps(body).encode(), method="POST")
    with urllib.request.urlopen(request, timeout=5) as r:
        return r.read()


def start(args, folder_text):
    process = subprocess.Popen([sys.executable, "-m", "toonforce.study", *args], stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True, env=os.environ.copy())
    url = None
    seen = []
    while url is None:
        line = process.stderr.readline()
        assert line, "".join(seen)
        seen.append(line)
        m = re.search(r"page: (http://\S+/)", line)
        url = m.group(1) if m else None
    return process, url, seen


def play(process, url, trials_file, stop_at=None):
    """Answers every prompt (the second interval; the scale's top) until the session ends, or
    presses the abort key once `stop_at` trials are on disk."""
    while process.poll() is None:
        if stop_at is not None and os.path.exists(trials_file) and open(trials_file).read().count("\n") >= stop_at:
            post(url + "abort", {})
            return
        try:
            state = get(url + "state")
        except OSError:
            time.sleep(0.02)
            continue
        if state["phase"] == "start":
            post(url + "answer", {"token": state["token"], "value": "start"})
        elif state["phase"] == "choice":
            post(url + "answer", {"token": state["token"], "value": 2})
        elif state["phase"] == "rating":
            post(url + "answer", {"token": state["token"], "value": {i["name"]: i["points"] for i in state["items"]}})
        elif state["phase"] == "break":
            post(url + "answer", {"token": state["token"], "value": "continue"})
        time.sleep(0.02)


def last_force(trace):
    with open(trace, newline="") as f:
        row = list(csv.DictReader(f))[-1]
    return float(row["fx"]), float(row["fy"]), float(row["fz"])


def test_a_person_answers_on_the_page_aborts_with_zero_force_and_resumes(tmp_path):
    experiment = tmp_path / "short.toml"
    experiment.write_text(EXPERIMENT)
    folder = tmp_path / "session"
    common = ["--hand", os.path.join(SCENES, "hands", "stroke.toml"), "--allow-non-rt", "--interval", "0.3"]
    process, url, seen = start(["run", str(experiment), "--participant", "1", "--out", str(folder), "--device", "sim",
                                *common], "")
    assert get(url + "state")["phase"] == "start"  # nothing plays before the participant's Start
    assert b'id="abort"' in urllib.request.urlopen(url, timeout=5).read()  # the page, with its abort key
    play(process, url, str(folder / "trials.jsonl"), stop_at=2)
    _, errors = process.communicate(timeout=60)
    assert process.returncode == 1 and "aborted by the participant (zero force)" in errors, errors
    kept = [json.loads(l) for l in open(folder / "trials.jsonl")]
    assert len(kept) >= 2 and all(t["answer"] == 2 for t in kept)
    assert all(t["correct"] == (not t["test_first"]) for t in kept)  # "the second" is right when the test was
    frames = [t["trace"]["frames"] for t in kept]  # each trial's part of the run's trace, in order
    assert all(t["trace"]["file"] == "run-1.csv" for t in kept)
    assert all(a < b <= c for (a, b), (c, _) in zip(frames, frames[1:] + [(10**9, 0)]))
    assert last_force(folder / "run-1.csv") == (0.0, 0.0, 0.0), "the abort ends the run on a zero-force tick"

    process, url, seen = start(["resume", str(folder), *common], "")  # the device is the session's
    play(process, url, str(folder / "trials.jsonl"))
    _, errors = process.communicate(timeout=120)
    assert process.returncode == 0, errors
    trials = [json.loads(l) for l in open(folder / "trials.jsonl")]
    assert len(trials) == 5  # 3 levels + 2 ratings: none lost, none repeated
    assert sorted(t["level"] for t in trials if "level" in t) == [1.0, 2.0, 4.0]
    assert [t["ratings"]["slippery"] for t in trials if "ratings" in t] == [5, 5]
    assert (folder / "done.json").exists()
    assert last_force(folder / "run-2.csv") == (0.0, 0.0, 0.0)
