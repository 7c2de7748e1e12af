# SPDX-License-Identifier: Apache-2.0
"""`toonforce study analyze SESSIONS...`: a Markdown report with plots, and its table as CSV and
JSON beside it. Per session and block: a staircase's track and threshold (mean of its last
reversals), a constant-stimuli block's psychometric fit (maximum likelihood from many starts,
with lapse) with its threshold, bootstrap 95 % interval, slope, lapse and goodness of fit, and
the flags saying what the data did not determine; then per block, the thresholds across
participants (those whose threshold is flagged left out unless asked; a slope or lapse at a
bound is a note and leaves the threshold in); ratings and paired comparisons tested per
participant and across participants (stats.py), never over pooled answers."""

from __future__ import annotations

import csv
import json
import os
from typing import Any, Dict, List, Sequence

import numpy as np

from . import psychometric, stats
from .session import Session


def block_result(session: Session, position: int, index: int, procedure, bootstrap_samples: int = 200) -> Dict[str, Any]:
    block = session.experiment.blocks[index]
    result: Dict[str, Any] = {"block": block.name, "index": index, "procedure": block.procedure,
                              "participant": session.meta["participant"], "trials": len(procedure.answers),
                              "levels": list(getattr(procedure, "levels", [])), "answers": list(procedure.answers)}
    if block.procedure == "rating":
        table: Dict[str, Dict[str, List[int]]] = {}
        for spec, res in zip(procedure._order, procedure.results):
            for item, value in res["ratings"].items():
                table.setdefault(item, {}).setdefault(spec["condition"], []).append(value)
        result["ratings"] = table
        return result
    if block.procedure == "task":
        metrics: Dict[str, Dict[str, List[Any]]] = {}
        for spec, res in zip(procedure._order, procedure.results):
            for key, value in res["metrics"].items():
                metrics.setdefault(spec["condition"], {}).setdefault(key, []).append(value)
        result["metrics"] = metrics
        return result
    if block.procedure == "paired-comparison":
        wins: Dict[str, int] = {c: 0 for spec in procedure._order for c in (spec["first"], spec["second"])}
        for spec, res in zip(procedure._order, procedure.results):
            chosen = spec["first"] if res["chose"] == 1 else spec["second"]
            wins[chosen] = wins.get(chosen, 0) + 1
        result["wins"] = wins
        return result
    if block.procedure == "constant-stimuli":
        levels, correct, trials = procedure.counts()
        if len(levels) >= 3:
            result.update(fitted(levels, correct, trials, block.options.get("form", "weibull"), bootstrap_samples,
                                 session.meta["seed"] + index))
    else:
        result.update(threshold=procedure.threshold(), reversal_levels=list(procedure.reversal_levels),
                      interval=psychometric.staircase_interval(procedure.reversal_levels[procedure.discard:]),
                      flags=[], threshold_flags=[])
    return result


def fitted(levels, correct, trials, form: str, bootstrap_samples: int, seed: int) -> Dict[str, Any]:
    """A constant-stimuli block's result: its assessed fit (psychometric.assess), with every flag
    and those that undermine the threshold."""
    a = psychometric.assess(levels, correct, trials, form, samples=bootstrap_samples, seed=seed)
    return {"threshold": a.fit.threshold, "interval": a.interval, "fit": a.fit, "assessment": a,
            "flags": list(a.flags), "threshold_flags": list(a.threshold_flags), "counts": (levels, correct, trials)}


def analyze(folders: Sequence[str], out_dir: str, bootstrap_samples: int = 200, include_flagged: bool = False) -> str:
    """Writes out_dir/report.md, its plots, results.csv and results.json; returns the report's
    path. `include_flagged`: flagged thresholds count in the means across participants."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    sessions = [Session(f) for f in folders]
    lines: List[str] = [f"# Study report: {sessions[0].experiment.name if sessions else '(no session)'}", ""]
    lines += ["Sessions: " + ", ".join(f"participant {s.meta['participant']} ({len(s.trials)} trials"
                                        f"{'' if s.done else ', not finished'})" for s in sessions), ""]
    per_block: Dict[str, List[Dict[str, Any]]] = {}
    rows: List[Dict[str, Any]] = []
    collected: Dict[str, List[Dict[str, Any]]] = {}  # rating and paired-comparison blocks, per participant
    for s in sessions:
        for position, index, procedure in s.procedures():
            r = block_result(s, position, index, procedure, bootstrap_samples)
            name = f"p{s.meta['participant']}_block{index + 1}"
            if r["procedure"] in ("rating", "paired-comparison", "task"):
                collected.setdefault(r["block"], []).append(r)
                continue
            fig, ax = plt.subplots(figsize=(6, 3.2))
            if r["procedure"] == "constant-stimuli" and "fit" in r:
                levels, correct, trials = r["counts"]
                ax.plot(levels, np.array(correct) / np.array(trials), "o", label="proportion correct")
                xs = np.linspace(min(levels) * 0.8, max(levels) * 1.1, 200)
                flagged = " (flagged)" if r["threshold_flags"] else ""
                ax.plot(xs, r["fit"].p(xs), label=f"{r['fit'].form} fit{flagged}")
                if min(levels) * 0.8 <= r["threshold"] <= max(levels) * 1.1:
                    ax.axvline(r["threshold"], ls="--", color="gray")
                ax.set_xlabel("level")
                ax.set_ylabel("proportion correct")
            else:
                ax.plot(range(1, len(r["levels"]) + 1), r["levels"], "-", color="gray")
                ok = np.array(r["answers"], dtype=bool)
                t = np.arange(1, len(r["levels"]) + 1)
                ax.plot(t[ok], np.array(r["levels"])[ok], "o", ms=3, label="correct")
                ax.plot(t[~ok], np.array(r["levels"])[~ok], "x", ms=4, label="wrong")
                if r["threshold"] is not None:
                    ax.axhline(r["threshold"], ls="--", color="gray")
                ax.set_xlabel("trial")
                ax.set_ylabel("level")
            ax.set_title(f"participant {s.meta['participant']}: {r['block']}")
            ax.legend(fontsize=7)
            fig.tight_layout()
            fig.savefig(os.path.join(out_dir, name + ".png"), dpi=90, metadata={"Software": None})
            plt.close(fig)
            lines.append(f"## Participant {s.meta['participant']}, {r['block']} ({r['procedure']}, {r['trials']} trials)")
            lines.append("")
            lines += _threshold_lines(r, bootstrap_samples)
            row = _row(s.meta["participant"], r, include_flagged)
            rows.append(row)
            if r.get("threshold") is not None:
                per_block.setdefault(r["block"], []).append(row)
            lines += ["", f"![{name}]({name}.png)", ""]
    group = across_participants(per_block)
    if per_block:
        lines += ["## Thresholds across participants", "",
                  "Flagged thresholds (above: not determined by their data) are " +
                  ("included, as asked (--include-flagged)." if include_flagged
                   else "left out (--include-flagged counts them).") +
                  " A note (the slope or the lapse rate at a bound) does not leave a threshold out.",
                  "", "| block | participants in the mean | mean | sd | flagged | with a note |",
                  "|---|---:|---:|---:|---:|---:|"]
        lines += [f"| {g['block']} | {g['participants']} | {g['mean']:.4g} | {g['sd']:.3g} | {g['flagged']} | "
                  f"{g['noted']} |" for g in group]
        lines.append("")
    tests: List[Dict[str, Any]] = []
    lines += _ratings_and_comparisons(collected, tests)
    path = os.path.join(out_dir, "report.md")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
    _write_tables(out_dir, rows, group, tests)
    return path


COLUMNS = ["participant", "block", "procedure", "trials", "threshold", "ci_low", "ci_high", "form", "alpha", "beta",
           "lapse", "slope", "log_likelihood", "deviance", "deviance_p", "lowest_level", "highest_level", "flags",
           "threshold_flags", "in_group_mean"]


def _row(participant, r: Dict[str, Any], include_flagged: bool = False) -> Dict[str, Any]:
    """A row of results.csv. It counts in the block's mean across participants when it has a
    threshold and no threshold flag (or `include_flagged`): notes alone do not leave it out."""
    row: Dict[str, Any] = {c: None for c in COLUMNS}
    row.update(participant=participant, block=r["block"], procedure=r["procedure"], trials=r["trials"],
               threshold=r.get("threshold"), flags=list(r.get("flags", [])),
               threshold_flags=list(r.get("threshold_flags", [])))
    if r.get("interval"):
        row["ci_low"], row["ci_high"] = r["interval"]
    if "assessment" in r:
        row.update({k: v for k, v in r["assessment"].as_dict().items() if k in COLUMNS})
    row["in_group_mean"] = row["threshold"] is not None and (include_flagged or not row["threshold_flags"])
    return row


def across_participants(per_block: Dict[str, List[Dict[str, Any]]]) -> List[Dict[str, Any]]:
    """Per block, the mean and sd of the thresholds of the rows in the mean; how many rows have a
    threshold flag (`flagged`), how many only notes (`noted`), how many are left out."""
    group = []
    for block, block_rows in per_block.items():
        v = np.array([row["threshold"] for row in block_rows if row["in_group_mean"]], dtype=float)
        group.append({"block": block, "participants": int(v.size), "mean": float(v.mean()) if v.size else float("nan"),
                      "sd": float(v.std(ddof=1)) if v.size > 1 else float("nan"),
                      "flagged": sum(1 for row in block_rows if row["threshold_flags"]),
                      "noted": sum(1 for row in block_rows if row["flags"] and not row["threshold_flags"]),
                      "left_out": sum(1 for row in block_rows if not row["in_group_mean"])})
    return group


def _write_tables(out_dir: str, rows: List[Dict[str, Any]], group, tests) -> None:
    with open(os.path.join(out_dir, "results.csv"), "w", encoding="utf-8", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({**row, "flags": "; ".join(row["flags"]),
                             "threshold_flags": "; ".join(row["threshold_flags"])})
    with open(os.path.join(out_dir, "results.json"), "w", encoding="utf-8") as f:
        json.dump({"thresholds": rows, "across_participants": group, "tests": tests}, f, indent=1,
                  default=lambda v: v.item() if hasattr(v, "item") else str(v))
        f.write("\n")


def _threshold_lines(r: Dict[str, Any], bootstrap_samples: int) -> List[str]:
    threshold, interval = r.get("threshold"), r.get("interval")
    if threshold is None:
        return ["No threshold yet (too few reversals or levels)."]
    if r["procedure"] != "constant-stimuli":
        return [f"Threshold {threshold:.4g}" + (f", t interval of its reversals (not calibrated) "
                                                f"[{interval[0]:.4g}, {interval[1]:.4g}]" if interval else "")]
    a = r["assessment"]
    f = a.fit
    out = []
    if a.threshold_flags:
        lo, hi = a.levels
        where = (f"it lies below the tested levels (< {lo:g}), where these data cannot place it" if threshold < lo
                 else f"it lies above the tested levels (> {hi:g}), where these data cannot place it" if threshold > hi
                 else f"it lies within the tested levels [{lo:g}, {hi:g}], but the data do not bound it")
        out += [f"Threshold not given as a number: {where}. The fit is flagged and left out of the means across "
                f"participants unless --include-flagged (results.csv has its values, for diagnosis).", "",
                "> **Warning**: " + "; ".join(a.flags) + ".", ""]
        out.append(f"For diagnosis only (not estimates), the fit's parameters: {f.form}, alpha {f.alpha:.2g}, "
                   f"beta {f.beta:.2g}, lapse {f.lapse:.2g}.")
    else:
        out.append(f"Threshold {threshold:.4g}, bootstrap 95 % interval [{interval[0]:.4g}, {interval[1]:.4g}] "
                   f"(parametric, {bootstrap_samples} refits, each from the multi-start fit)")
        out += ["", f"Fit: {f.form}, alpha {f.alpha:.4g}, beta {f.beta:.4g}, lapse {f.lapse:.3g}; slope at the "
                    f"threshold dP/dx {f.slope:.3g}"]
        if a.notes:
            out += ["", "> **Note**: " + "; ".join(a.notes) + ". The threshold lies within the tested levels and "
                    "its interval is bounded by the data: it counts in the means across participants; the slope "
                    "and lapse rate are not estimates."]
    fits = "the function does not describe these answers" if a.deviance_p < 0.05 else "no evidence of misfit"
    out += ["", f"Goodness of fit: deviance {a.deviance:.3g}, bootstrap p = {a.deviance_p:.3g} "
                f"(the refits' deviances at least as large; {fits} at 0.05)"]
    return out


def _ratings_and_comparisons(collected: Dict[str, List[Dict[str, Any]]], tests: List[Dict[str, Any]]) -> List[str]:
    """Per rating item: each condition's median rating per participant, and between two
    conditions the Wilcoxon signed-rank test across participants (each participant's median).
    Per paired comparison: each participant's choices with an exact binomial test against no
    preference, and across participants a Wilcoxon signed-rank and a sign test of the
    participants' proportions against 1/2. Answers are never pooled over participants for a
    test: one person's answers are not independent of each other."""
    out: List[str] = []
    for block, results in collected.items():
        out += [f"## {block} ({results[0]['procedure']}, {len(results)} participants)", ""]
        if results[0]["procedure"] == "task":
            conditions = sorted({c for r in results for c in r["metrics"]})
            keys = sorted({k for r in results for c in r["metrics"].values() for k in c})
            out += ["| condition | " + " | ".join(keys) + " |", "|---|" + "---:|" * len(keys)]
            for c in conditions:
                cells = []
                for k in keys:
                    values = [v for r in results for v in r["metrics"].get(c, {}).get(k, [])]
                    numbers = [float(v) for v in values if v is not None]
                    if k == "success":
                        cells.append(f"{sum(bool(v) for v in values)} of {len(values)}")
                    else:
                        cells.append(f"{np.mean(numbers):.4g}" if numbers else "n/a")
                out.append(f"| {c} | " + " | ".join(cells) + " |")
            out += ["", "Means over every trial of every participant; success as a count."]
        elif results[0]["procedure"] == "rating":
            items = sorted({item for r in results for item in r["ratings"]})
            conditions = sorted({c for r in results for table in r["ratings"].values() for c in table})
            out += ["| item | " + " | ".join(f"{c}: median (participants' medians)" for c in conditions) +
                    " | rank-biserial r | Wilcoxon p |", "|---|" + "---|" * len(conditions) + "---:|---:|"]
            methods = set()
            for item in items:
                medians = {c: [float(np.median(r["ratings"][item][c])) for r in results] for c in conditions}
                p_text, r_text = "n/a", "n/a"
                if len(conditions) == 2 and len(results) >= 2:
                    a, b = np.array(medians[conditions[0]]), np.array(medians[conditions[1]])
                    if np.any(a != b):
                        t = stats.wilcoxon(a - b)
                        p_text, r_text = f"{t.pvalue:.3g}", f"{t.effect:+.2f}"
                        methods.add(t.name)
                        tests.append({"block": block, "item": item, "comparison": f"{conditions[0]} - {conditions[1]}",
                                      "across": "participants' medians", **vars(t)})
                cells = [f"{np.median(medians[c]):g} ({', '.join(f'{m:g}' for m in medians[c])})" for c in conditions]
                out.append(f"| {item} | " + " | ".join(cells) + f" | {r_text} | {p_text} |")
            if methods:
                out += ["", f"Across participants, on each one's median, {conditions[0]} minus {conditions[1]} "
                            f"(r > 0: {conditions[0]} rated higher): " + "; ".join(sorted(methods)) +
                        ". Two-sided; the effect size is the matched-pairs rank-biserial correlation (Kerby 2014)."]
        else:
            out += _paired_comparison(block, results, tests)
        out.append("")
    return out


def _paired_comparison(block: str, results: List[Dict[str, Any]], tests: List[Dict[str, Any]]) -> List[str]:
    totals: Dict[str, int] = {}
    for r in results:
        for c, n in r["wins"].items():
            totals[c] = totals.get(c, 0) + n
    n = sum(totals.values())
    names = sorted(totals)
    out = [", ".join(f"{c} chosen {totals[c]} of {n}" for c in names) +
           " (all participants' answers together: a description; the tests below are per participant and "
           "across participants)"]
    if len(names) != 2:
        return out + ["", "No test: more than two conditions."]
    first = max(names, key=lambda c: (totals[c], c))  # the proportions are of the one chosen more
    out += ["", f"| participant | {first} chosen | answers | exact binomial p | Cohen's g |", "|---|---:|---:|---:|---:|"]
    proportions = []
    for r in results:
        wins, answers = r["wins"].get(first, 0), sum(r["wins"].values())
        if answers == 0:
            continue
        t = stats.binomial(wins, answers)
        proportions.append(wins / answers)
        out.append(f"| {r['participant']} | {wins} | {answers} | {t.pvalue:.3g} | {t.effect:+.2f} |")
        tests.append({"block": block, "participant": r["participant"], "comparison": f"{first} chosen",
                      **vars(t)})
    d = np.array(proportions) - 0.5
    out += ["", f"Across participants, each one's proportion choosing {first} against 1/2 (two-sided):", ""]
    if not np.any(d != 0):
        return out + ["- no test: every participant chose each condition equally often"]
    for t in (stats.wilcoxon(d), stats.sign_test(d)):
        out.append(f"- {t.text()}")
        tests.append({"block": block, "across": "participants' proportions", "comparison": f"{first} chosen", **vars(t)})
    return out
