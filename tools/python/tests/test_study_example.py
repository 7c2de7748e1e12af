# SPDX-License-Identifier: Apache-2.0
"""The example JND study (scenes/studies/ice_jnd.toml, docs/STUDIES.md): a few simulated
participants whose JND of cartoon ice's mu is known play it on the simulated device through the
command line; the report must place their thresholds on the staircase and constant-stimuli
blocks without a flag, and flag the check block (answers at chance) and leave it out of the
means across participants."""

import csv
import json
import os
import subprocess
import sys

import pytest
from scipy.stats import norm

from toonforce.study.analysis import analyze

SOURCE_DIR = os.environ.get("TOONFORCE_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
STUDY = os.path.join(SOURCE_DIR, "scenes", "studies", "ice_jnd.toml")
REFERENCE = 2.0  # [N s/m] the reference mu of the example
THRESHOLD = 2.5  # [N s/m] the simulated participants' 75 % point: a JND of 0.5, 25 %
PARTICIPANTS = 4
GOOD = ("staircase on mu", "constant stimuli on mu")
CHECK = "check: increments below the JND"


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ice_jnd")
    folders = []
    for participant in range(1, PARTICIPANTS + 1):
        folder = str(tmp / f"p{participant}")
        done = subprocess.run([sys.executable, "-m", "toonforce.study", "run", STUDY, "--out", folder,
                               "--participant", str(participant), "--seed", str(participant),
                               "--simulated-threshold", str(THRESHOLD), "--simulated-lapse", "0.02"],
                              capture_output=True, text=True, env=os.environ.copy(), timeout=600)
        assert done.returncode == 0, done.stderr
        folders.append(folder)
    out = tmp / "report"
    text = open(analyze(folders, str(out), bootstrap_samples=100)).read()
    with open(out / "results.csv") as f:
        rows = list(csv.DictReader(f))
    return text, rows, json.load(open(out / "results.json"))


def test_every_participant_played_the_three_blocks(report):
    _, rows, _ = report
    assert sorted((int(r["participant"]), r["block"]) for r in rows) == sorted(
        (p, b) for p in range(1, PARTICIPANTS + 1) for b in GOOD + (CHECK,))


def test_the_good_blocks_are_not_flagged_and_count_in_the_means(report):
    text, rows, table = report
    for r in rows:
        if r["block"] in GOOD:
            assert r["flags"] == "" and r["in_group_mean"] == "True", r
            section = text.split(f"## Participant {r['participant']}, {r['block']} (")[1].split("\n## ")[0]
            assert "Warning" not in section and "Note" not in section and "Threshold not given" not in section
    group = {g["block"]: g for g in table["across_participants"]}
    for block in GOOD:
        assert group[block]["participants"] == PARTICIPANTS and group[block]["flagged"] == 0
        assert group[block]["noted"] == 0 and group[block]["left_out"] == 0
    # They measure the JND they were given: constant stimuli at 75 % correct, the staircase at
    # 70.7 % (Levitt 1971); the push is proportional to mu here (mu v, far below its cap), so
    # the 70.7 % point's JND is the 75 % one's times Phi^-1(p') / Phi^-1(3/4), p' the
    # probability without lapses. Within 30 % of the JND, for four participants.
    jnd = THRESHOLD - REFERENCE
    p = (0.5 ** 0.5 - 0.01) / 0.98
    staircase_jnd = jnd * norm.ppf(p) / norm.ppf(0.75)
    assert group["constant stimuli on mu"]["mean"] - REFERENCE == pytest.approx(jnd, rel=0.3)
    assert group["staircase on mu"]["mean"] - REFERENCE == pytest.approx(staircase_jnd, rel=0.3)


def test_the_check_block_is_flagged_and_left_out_of_the_means(report):
    text, rows, table = report
    checks = [r for r in rows if r["block"] == CHECK]
    assert len(checks) == PARTICIPANTS
    for r in checks:
        assert "threshold above the tested levels" in r["threshold_flags"] and r["in_group_mean"] == "False", r
        section = text.split(f"## Participant {r['participant']}, {CHECK} (")[1].split("\n## ")[0]
        assert "Threshold not given as a number: it lies above the tested levels" in section
        assert "> **Warning**: threshold above the tested levels" in section
    group = {g["block"]: g for g in table["across_participants"]}[CHECK]
    assert group["participants"] == 0 and group["flagged"] == PARTICIPANTS and group["left_out"] == PARTICIPANTS
