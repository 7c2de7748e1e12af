# SPDX-License-Identifier: Apache-2.0
"""toonforce.study's analysis: psychometric fits that find the likelihood's maximum and flag what
the data do not determine (checked against a fine grid of the log-likelihood), bootstrap
intervals that cover a known threshold, the Wilcoxon test against scipy and exact enumeration,
and tests across participants rather than over pooled answers."""

import csv
import itertools
import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.stats import binomtest, rankdata
from scipy.stats import wilcoxon as scipy_wilcoxon

from toonforce.study import psychometric, stats
from toonforce.study.analysis import _paired_comparison, _row, _threshold_lines, across_participants, analyze, fitted

SOURCE_DIR = os.environ.get("TOONFORCE_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
STUDY = os.path.join(SOURCE_DIR, "scenes", "studies", "cartoon_ice.toml")
LEVELS = np.array([0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0])  # the example study's constant stimuli
TRIALS = np.full(7, 20)


def log_likelihood(form, alpha, beta, lapse, k, x=LEVELS, n=TRIALS):
    """The binomial log-likelihood written out here, independent of psychometric.py
    (broadcasting over parameter arrays)."""
    with np.errstate(over="ignore", divide="ignore", under="ignore"):
        if form == "weibull":
            f = 1 - np.exp(-(x / alpha) ** beta)
        else:
            f = 1 / (1 + np.exp(-(x - alpha) / beta))
    p = np.clip(0.5 + (0.5 - lapse) * f, 1e-300, 1)
    q = np.clip(0.5 - (0.5 - lapse) * f, 1e-300, 1)
    return np.sum(k * np.log(p) + (n - k) * np.log(q), axis=-1)


def fine_grid_maximum(form, k):
    """The log-likelihood's maximum on a fine grid, and the threshold there."""
    if form == "weibull":
        a = np.geomspace(0.3, 3.0, 400)[:, None, None, None]
        b = np.geomspace(0.3, 20.0, 200)[None, :, None, None]
    else:
        a = np.linspace(0.0, 3.0, 400)[:, None, None, None]
        b = np.geomspace(0.01, 3.0, 200)[None, :, None, None]
    lapse = np.linspace(0, 0.06, 25)[None, None, :, None]
    ll = log_likelihood(form, a, b, lapse, np.asarray(k))
    i, j, m = np.unravel_index(np.argmax(ll), ll.shape)
    alpha, beta = a.ravel()[i], b.ravel()[j]
    threshold = alpha * np.log(2) ** (1 / beta) if form == "weibull" else alpha
    return float(ll.max()), float(threshold)


# Non-monotonic answers drawn from a Weibull observer (threshold 1.2): the likelihood has a
# second maximum (lapse 0, shallow) 0.5-1 below the global one (lapse 0.05, steep).
NON_MONOTONIC = [[9, 7, 12, 17, 18, 19, 20], [15, 7, 11, 11, 19, 18, 20]]


@pytest.mark.parametrize("k", NON_MONOTONIC)
def test_the_fit_finds_the_global_maximum_a_single_start_misses(k):
    k = np.array(k)
    grid_ll, grid_threshold = fine_grid_maximum("weibull", k)
    # One local search from the middle of the levels stops on the other maximum.
    single = minimize(lambda v: -log_likelihood("weibull", v[0], v[1], v[2], k), x0=[1.0, 3.0, 0.01],
                      method="L-BFGS-B", bounds=[(0.01, 30), (0.1, 50), (0, 0.06)])
    assert -single.fun < grid_ll - 0.3, (-single.fun, grid_ll)
    fit = psychometric.fit(LEVELS, k, TRIALS, "weibull")
    assert fit.log_likelihood >= grid_ll - 1e-6, (fit, grid_ll)
    assert abs(fit.log_likelihood - log_likelihood("weibull", fit.alpha, fit.beta, fit.lapse, k)) < 1e-9
    assert abs(fit.threshold / grid_threshold - 1) < 0.02, (fit.threshold, grid_threshold)
    assert not fit.at_bound


@pytest.mark.parametrize("form", ["weibull", "logistic"])
def test_fits_of_example_data_reach_the_fine_grids_maximum(form):
    rng = np.random.default_rng(3)
    truth = psychometric.Fit("weibull", 1.2 / np.log(2) ** (1 / 2.5), 2.5, 0.02, 0.5, 0.0)
    for _ in range(10):
        k = rng.binomial(TRIALS, truth.p(LEVELS))
        fit = psychometric.fit(LEVELS, k, TRIALS, form)
        assert fit.log_likelihood >= fine_grid_maximum(form, k)[0] - 1e-6, (k, fit)


DEGENERATE = {
    # name: (answers correct of 20 per level, what must be flagged)
    "flat": ([10] * 7, ["threshold above the tested levels", "alpha at its upper bound"]),
    "all correct": ([20] * 7, ["threshold below the tested levels", "alpha at its lower bound", "interval of zero width"]),
    "a step between two levels": ([10, 10, 10, 20, 20, 20, 20], ["beta at its upper bound"]),
    "rising past the highest level": ([10, 10, 11, 11, 12, 13, 14], ["threshold above the tested levels"]),
}


@pytest.mark.parametrize("name", sorted(DEGENERATE))
@pytest.mark.parametrize("form", ["weibull", "logistic"])
def test_degenerate_fits_are_flagged(name, form):
    k, expected = DEGENERATE[name]
    if form == "logistic":  # its beta is a scale: steep at its lower bound
        expected = [f.replace("beta at its upper", "beta at its lower") for f in expected]
    a = psychometric.assess(LEVELS, k, TRIALS, form, samples=60, seed=2)
    for flag in expected:
        assert any(flag in f for f in a.flags), (flag, a.flags, a.fit)
    lo, hi = a.interval
    if not a.levels[0] <= a.fit.threshold <= a.levels[1]:
        return
    # A step: the threshold is inside, between the levels the answers jump at.
    assert 0.75 <= a.fit.threshold <= 1.0 and hi > lo


def test_a_well_posed_session_is_not_flagged_and_its_deviance_fits():
    truth = psychometric.Fit("weibull", 1.2 / np.log(2) ** (1 / 2.5), 2.5, 0.02, 0.5, 0.0)
    expected = np.rint(truth.p(LEVELS) * TRIALS).astype(int)  # the observer's expected answers
    a = psychometric.assess(LEVELS, expected, TRIALS, samples=100, seed=1)
    assert not a.flags, a.flags
    assert a.interval[0] < 1.2 < a.interval[1]
    assert a.deviance_p > 0.3, a.deviance_p  # the truth describes its expected answers
    k = np.array(expected)
    p_hat = k / TRIALS
    with np.errstate(divide="ignore", invalid="ignore"):
        saturated = np.sum(np.where(k > 0, k * np.log(p_hat), 0) + np.where(k < 20, (20 - k) * np.log(1 - p_hat), 0))
    assert abs(a.deviance - 2 * (saturated - a.fit.log_likelihood)) < 1e-9
    # Answers that go down where the function must go up: the deviance says so.
    u_shaped = psychometric.assess(LEVELS, [18, 16, 12, 10, 12, 16, 20], TRIALS, samples=100, seed=1)
    assert u_shaped.deviance_p < 0.05, u_shaped.deviance_p


def test_bootstrap_intervals_cover_the_truth_in_most_simulated_sessions():
    truth = psychometric.Fit("weibull", 1.2 / np.log(2) ** (1 / 2.5), 2.5, 0.02, 0.5, 0.0)
    rng = np.random.default_rng(2024)
    covered, flagged, sessions = 0, 0, 40
    for seed in range(sessions):
        k = rng.binomial(TRIALS, truth.p(LEVELS))
        a = psychometric.assess(LEVELS, k, TRIALS, samples=100, seed=seed)
        covered += a.interval[0] <= 1.2 <= a.interval[1]
        flagged += a.flagged
    assert covered >= 35, f"the 95 % interval covered the truth in {covered} of {sessions}"
    assert flagged <= 2, f"{flagged} of {sessions} well-posed sessions had their threshold flagged"


def test_a_slope_at_its_bound_is_a_note_and_its_threshold_counts_in_the_mean():
    # Three participants' blocks: expected answers of the Weibull observer, answers that jump
    # between 0.75 and 1.0 (steeper than the levels resolve: beta at its bound, the threshold
    # between them), and answers at chance (no threshold).
    truth = psychometric.Fit("weibull", 1.2 / np.log(2) ** (1 / 2.5), 2.5, 0.02, 0.5, 0.0)
    answers = {"good": np.rint(truth.p(LEVELS) * TRIALS).astype(int), "step": [10, 10, 10, 20, 20, 20, 20],
               "flat": [10] * 7}
    results = {name: {"block": "b", "procedure": "constant-stimuli", "trials": 140,
                      **fitted(LEVELS, k, TRIALS, "weibull", 60, 2)} for name, k in answers.items()}
    step, flat = results["step"]["assessment"], results["flat"]["assessment"]
    assert any(f.startswith("beta at its upper bound (the slope is not determined: steeper") for f in step.flags)
    assert not step.threshold_flags and step.notes == step.flags and not step.flagged
    assert 0.75 <= step.fit.threshold <= 1.0
    assert any(f.startswith("threshold above the tested levels") for f in flat.threshold_flags) and flat.flagged
    rows = [_row(i + 1, results[name]) for i, name in enumerate(("good", "step", "flat"))]
    assert [r["in_group_mean"] for r in rows] == [True, True, False]
    assert rows[1]["flags"] == step.flags and rows[1]["threshold_flags"] == []
    group = across_participants({"b": rows})[0]
    assert group["participants"] == 2 and group["left_out"] == 1 and group["flagged"] == 1 and group["noted"] == 1
    assert group["mean"] == pytest.approx((results["good"]["threshold"] + step.fit.threshold) / 2)
    text = "\n".join(_threshold_lines(results["step"], 60))
    assert f"Threshold {step.fit.threshold:.4g}, bootstrap 95 % interval" in text
    assert "> **Note**: beta at its upper bound" in text and "Warning" not in text
    text = "\n".join(_threshold_lines(results["flat"], 60))
    assert "Threshold not given as a number" in text and "**Warning**" in text
    # --include-flagged: the flat one counts too.
    assert all(_row(1, r, include_flagged=True)["in_group_mean"] for r in results.values())


def brute_force_exact(d, zero_method):
    """Two-sided p of the signed-rank sum, every sign assignment enumerated."""
    d = np.asarray(d, dtype=float)
    if zero_method == "wilcox":
        d = d[d != 0]
    r = rankdata(np.abs(d))
    nonzero = r[d != 0]
    observed = r[d > 0].sum()
    sums = np.array([np.dot(nonzero, s) for s in itertools.product([0, 1], repeat=nonzero.size)])
    return min(1.0, 2 * min(np.mean(sums <= observed + 1e-9), np.mean(sums >= observed - 1e-9)))


CASES = [
    [0, 0, 1, 1, 2, 2, 3, -1],           # zeros and ties
    [0.5] * 8,                          # every participant the same: all tied
    [1, 2, 3, 4, 5, -6, 7, 8],           # neither
    [0, 1, 1, 1, -2, 3, 3, 0, 4, -4, 5, 6],
    [2, 0, 0, 1, 1, 3],                 # the reviewer's kind: two zeros, the rest positive
    list(np.round(np.random.default_rng(1).normal(size=30), 1)),
]


@pytest.mark.parametrize("d", CASES)
def test_wilcoxon_matches_scipy_and_exact_enumeration_with_zeros_and_ties(d):
    warnings.simplefilter("ignore")  # scipy warns on small samples for the approximation
    for zero_method in ("wilcox", "pratt", "zsplit"):
        for correction in (False, True):
            ours = stats.wilcoxon(d, zero_method, correction, "approx")
            theirs = scipy_wilcoxon(d, zero_method=zero_method, correction=correction, method="approx")
            assert ours.statistic == pytest.approx(theirs.statistic, abs=1e-12)
            assert ours.pvalue == pytest.approx(theirs.pvalue, rel=1e-12), (zero_method, correction)
            assert "normal approximation" in ours.name and zero_method in ours.name
        if len(d) <= 16:
            assert stats.wilcoxon(d, zero_method, method="exact").pvalue == pytest.approx(
                brute_force_exact(d, zero_method), rel=1e-12)
    if np.all(np.asarray(d) != 0) and len(set(np.abs(d))) == len(d):  # scipy's exact: no zeros, no ties
        assert stats.wilcoxon(d, method="exact").pvalue == pytest.approx(
            scipy_wilcoxon(d, method="exact").pvalue, rel=1e-12)
    r = stats.wilcoxon(d)
    ranks = rankdata(np.abs(np.asarray(d)[np.asarray(d) != 0]))
    nz = np.asarray(d)[np.asarray(d) != 0]
    assert r.effect == pytest.approx((ranks[nz > 0].sum() - ranks[nz < 0].sum()) / ranks.sum())


def test_two_zeros_and_six_positive_differences_give_the_exact_p_of_six():
    # Dropping the zeros (Wilcoxon 1945) leaves 6 positive differences: 2 / 2^6.
    result = stats.wilcoxon([2, 0, 0, 1, 1, 3, 2, 1])
    assert result.pvalue == pytest.approx(2 / 64) and "exact" in result.name and "zero_method=wilcox" in result.name


def test_paired_comparisons_are_tested_across_participants_not_over_pooled_answers():
    # One participant always chose A (100 answers); seven chose at chance (10 answers each).
    chose = [100, 5, 4, 6, 5, 6, 4, 5]
    answers = [100] + [10] * 7
    results = [{"participant": i, "wins": {"A": c, "B": n - c}} for i, (c, n) in enumerate(zip(chose, answers))]
    pooled = binomtest(sum(chose), sum(answers), 0.5).pvalue
    assert pooled < 1e-6  # what pooling the answers would claim
    tests = []
    lines = _paired_comparison("block", results, tests)
    across = {t["name"].split(",")[0]: t for t in tests if t.get("across")}
    d = np.array(chose) / np.array(answers) - 0.5
    assert across["Wilcoxon signed-rank"]["pvalue"] == pytest.approx(brute_force_exact(d, "wilcox"))
    assert across["sign test"]["pvalue"] == pytest.approx(binomtest(3, 5, 0.5).pvalue)
    assert min(t["pvalue"] for t in across.values()) > 0.3
    per_participant = [t for t in tests if "participant" in t]
    assert [t["pvalue"] for t in per_participant] == pytest.approx(
        [binomtest(c, n, 0.5).pvalue for c, n in zip(chose, answers)])
    text = "\n".join(lines)
    assert "rank-biserial r" in text and "Cohen's g" in text and "zero_method=wilcox" in text


def constant_stimuli_only(tmp_path):
    """The example study with its constant-stimuli block alone, paths made absolute."""
    text = open(STUDY).read().replace('"../', f'"{SOURCE_DIR}/scenes/').replace(
        '"floor.toml"', f'"{SOURCE_DIR}/scenes/studies/floor.toml"')
    head, *blocks = text.split("[[block]]")
    conditions = "".join("[[condition]]" + c for b in blocks for c in b.split("[[condition]]")[1:])
    kept = [b.split("[[condition]]")[0] for b in blocks if 'procedure = "constant-stimuli"' in b]
    path = tmp_path / "constant.toml"
    path.write_text(head + conditions + "[[block]]" + kept[0])
    return str(path)


def test_the_report_flags_an_undetermined_threshold_and_leaves_it_out_of_the_mean(tmp_path):
    study = constant_stimuli_only(tmp_path)
    folders = []
    for participant, threshold in ((1, 1.2), (2, 1.2), (3, 40.0)):  # 3: far above the levels
        folder = str(tmp_path / f"p{participant}")
        done = subprocess.run([sys.executable, "-m", "toonforce.study", "run", study, "--out", folder,
                               "--participant", str(participant), "--seed", str(participant),
                               "--simulated-threshold", str(threshold)],
                              capture_output=True, text=True, env=os.environ.copy(), timeout=600)
        assert done.returncode == 0, done.stderr
        folders.append(folder)
    out = tmp_path / "report"
    text = open(analyze(folders, str(out), bootstrap_samples=40)).read()
    with open(out / "results.csv") as f:
        rows = list(csv.DictReader(f))
    table = json.load(open(out / "results.json"))
    assert [r["participant"] for r in rows] == ["1", "2", "3"]
    assert table["thresholds"][2]["flags"] and "threshold above the tested levels" in rows[2]["flags"]
    assert rows[2]["in_group_mean"] == "False" and rows[0]["in_group_mean"] == "True"
    section = text.split("## Participant 3")[1].split("##")[0]
    assert "Threshold not given as a number: it lies above the tested levels" in section and "**Warning**" in section
    assert f"{float(rows[2]['threshold']):.4g}" not in section  # no value printed for it
    good = [float(r["threshold"]) for r in rows if r["in_group_mean"] == "True"]
    assert len(good) == 2 and table["across_participants"][0]["left_out"] == 1
    assert table["across_participants"][0]["mean"] == pytest.approx(np.mean(good))
    for r in rows[:2]:  # the determined ones: slope, lapse, goodness of fit in the table
        assert float(r["slope"]) > 0 and 0 <= float(r["lapse"]) <= 0.06 and 0 <= float(r["deviance_p"]) <= 1
    included = json.load(open(os.path.join(os.path.dirname(analyze(folders, str(tmp_path / "all"), 40, True)),
                                            "results.json")))
    assert included["across_participants"][0]["participants"] == 3
    assert included["across_participants"][0]["flagged"] == 1 and included["across_participants"][0]["left_out"] == 0
