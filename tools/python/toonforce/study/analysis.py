# SPDX-License-Identifier: Apache-2.0
"""`toonforce study analyze SESSIONS...`: a Markdown report with plots. Per session
and block: a staircase's track and threshold (mean of its last reversals), a constant-stimuli
block's psychometric fit (maximum likelihood, with lapse) with its threshold and bootstrap
95 % interval; then per block, the thresholds across participants."""

from __future__ import annotations

import os
from typing import Any, Dict, List, Sequence

import numpy as np

from . import psychometric
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
            fit = psychometric.fit(levels, correct, trials, block.options.get("form", "weibull"))
            lo, hi = psychometric.bootstrap(fit, levels, trials, samples=bootstrap_samples,
                                            seed=session.meta["seed"] + index)
            result.update(threshold=fit.threshold, interval=(lo, hi), fit=fit, counts=(levels, correct, trials))
    else:
        result.update(threshold=procedure.threshold(), reversal_levels=list(procedure.reversal_levels),
                      interval=psychometric.staircase_interval(procedure.reversal_levels[procedure.discard:]))
    return result


def analyze(folders: Sequence[str], out_dir: str, bootstrap_samples: int = 200) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    sessions = [Session(f) for f in folders]
    lines: List[str] = [f"# Study report: {sessions[0].experiment.name if sessions else '(no session)'}", ""]
    lines += ["Sessions: " + ", ".join(f"participant {s.meta['participant']} ({len(s.trials)} trials"
                                        f"{'' if s.done else ', not finished'})" for s in sessions), ""]
    per_block: Dict[str, List[float]] = {}
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
                ax.plot(xs, r["fit"].p(xs), label=f"{r['fit'].form} fit")
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
            threshold = r.get("threshold")
            interval = r.get("interval")
            lines.append(f"## Participant {s.meta['participant']}, {r['block']} ({r['procedure']}, {r['trials']} trials)")
            lines.append("")
            if threshold is None:
                lines.append("No threshold yet (too few reversals or levels).")
            else:
                what = ("bootstrap 95 % interval" if r["procedure"] == "constant-stimuli"
                        else "t interval of its reversals (not calibrated)")
                lines.append(f"Threshold {threshold:.4g}" + (f", {what} [{interval[0]:.4g}, {interval[1]:.4g}]"
                                                            if interval else ""))
                per_block.setdefault(r["block"], []).append(threshold)
            lines += ["", f"![{name}]({name}.png)", ""]
    lines += ["## Thresholds across participants", "", "| block | participants | mean | sd |", "|---|---:|---:|---:|"]
    for block, values in per_block.items():
        v = np.array(values)
        lines.append(f"| {block} | {v.size} | {v.mean():.4g} | {v.std(ddof=1) if v.size > 1 else float('nan'):.3g} |")
    lines += _ratings_and_comparisons(collected)
    path = os.path.join(out_dir, "report.md")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
    return path


def _ratings_and_comparisons(collected: Dict[str, List[Dict[str, Any]]]) -> List[str]:
    """Per rating item: each condition's median rating per participant, and between two
    conditions the Wilcoxon signed-rank test across participants (each participant's median).
    Per paired comparison: how often each condition was chosen, and a two-sided binomial test
    against no preference over all answers."""
    from scipy.stats import binomtest, wilcoxon

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
            out += ["| item | " + " | ".join(f"{c}: median (participants' medians)" for c in conditions) + " | Wilcoxon p |",
                    "|---|" + "---|" * len(conditions) + "---:|"]
            for item in items:
                medians = {c: [float(np.median(r["ratings"][item][c])) for r in results] for c in conditions}
                p_text = "n/a"
                if len(conditions) == 2 and len(results) >= 2:
                    a, b = np.array(medians[conditions[0]]), np.array(medians[conditions[1]])
                    if np.any(a != b):
                        p_text = f"{wilcoxon(a, b).pvalue:.3g}"
                cells = [f"{np.median(medians[c]):g} ({', '.join(f'{m:g}' for m in medians[c])})" for c in conditions]
                out.append(f"| {item} | " + " | ".join(cells) + f" | {p_text} |")
        else:
            totals: Dict[str, int] = {}
            for r in results:
                for c, n in r["wins"].items():
                    totals[c] = totals.get(c, 0) + n
            n = sum(totals.values())
            names = sorted(totals)
            top = max(totals.values())
            p = binomtest(top, n, 0.5).pvalue if len(names) == 2 else float("nan")
            out.append(", ".join(f"{c} chosen {totals[c]} of {n}" for c in names) +
                       f" (binomial test against no preference: p = {p:.3g})")
        out.append("")
    return out
