# SPDX-License-Identifier: Apache-2.0
"""Psychometric functions fitted by maximum likelihood (scipy), with bootstrap confidence
intervals, for two-interval forced choice (guess rate 1/2) and other designs.

    P(correct | x) = guess + (1 - guess - lapse) * F(x)

F is a Weibull, 1 - exp(-(x / alpha)^beta) (x > 0), or a logistic, 1 / (1 + exp(-(x - alpha) /
beta)). The threshold is where F = 1/2 (75 % correct in 2IFC without lapses): alpha * ln(2)^(1 /
beta) for the Weibull, alpha for the logistic. The lapse rate is fitted in [0, max_lapse]
(Wichmann and Hill 2001). The confidence interval is a parametric bootstrap's percentile
interval: new answers drawn from the fitted function at the same levels and trial counts,
refitted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np
from scipy.optimize import minimize


@dataclass
class Fit:
    form: str
    alpha: float
    beta: float
    lapse: float
    guess: float
    log_likelihood: float

    def f(self, x):
        x = np.asarray(x, dtype=float)
        if self.form == "weibull":
            return 1.0 - np.exp(-np.power(np.maximum(x, 0.0) / self.alpha, self.beta))
        return 1.0 / (1.0 + np.exp(-(x - self.alpha) / self.beta))

    def p(self, x):
        """The fitted proportion correct at x."""
        return self.guess + (1.0 - self.guess - self.lapse) * self.f(x)

    @property
    def threshold(self) -> float:
        """x where F = 1/2."""
        if self.form == "weibull":
            return self.alpha * math.log(2.0) ** (1.0 / self.beta)
        return self.alpha


def _nll(params, form, x, k, n, guess):
    """The negative log-likelihood and its gradient in (alpha, beta, lapse)."""
    a, b, lapse = params
    scale = 1.0 - guess - lapse
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # far-off trial points
        return _nll_terms(a, b, lapse, scale, form, x, k, n, guess)


def _nll_terms(a, b, lapse, scale, form, x, k, n, guess):
    if form == "weibull":
        u = np.power(np.maximum(x, 0.0) / a, b)
        f = 1.0 - np.exp(-u)
        df_du = np.exp(-u)
        df_da = df_du * (-b * u / a)
        df_db = df_du * u * np.log(np.maximum(x, 1e-300) / a)
    else:
        z = (x - a) / b
        f = 1.0 / (1.0 + np.exp(-z))
        df_dz = f * (1.0 - f)
        df_da = df_dz * (-1.0 / b)
        df_db = df_dz * (-z / b)
    p = np.clip(guess + scale * f, 1e-12, 1.0 - 1e-12)
    nll = -float(np.sum(k * np.log(p) + (n - k) * np.log(1.0 - p)))
    dnll_dp = -(k / p - (n - k) / (1.0 - p))
    grad = np.nan_to_num(np.array([np.sum(dnll_dp * scale * df_da), np.sum(dnll_dp * scale * df_db),
                                   np.sum(dnll_dp * -f)]), nan=0.0, posinf=1e300, neginf=-1e300)
    return nll, grad


def fit(levels: Sequence[float], correct: Sequence[int], trials: Sequence[int], form: str = "weibull",
        guess: float = 0.5, max_lapse: float = 0.06, start: Optional[Fit] = None) -> Fit:
    """The maximum-likelihood fit of answers counted per level (from `start` alone if given:
    the bootstrap's refits start from the fit they resample)."""
    if form not in ("weibull", "logistic"):
        raise ValueError(f"form must be 'weibull' or 'logistic' (got {form!r})")
    x = np.asarray(levels, dtype=float)
    k = np.asarray(correct, dtype=float)
    n = np.asarray(trials, dtype=float)
    if form == "weibull" and np.any(x <= 0):
        raise ValueError("a Weibull needs levels > 0")
    span = float(x.max() - x.min()) or 1.0
    if start is not None:
        starts = [(start.alpha, start.beta)]
    else:  # a few starts across the levels: the likelihood of a few hundred answers has flat parts
        starts = [(float(a0), b0) for a0 in np.quantile(x, [0.25, 0.5, 0.75])
                  for b0 in ((1.5, 3.0) if form == "weibull" else (span / 8, span / 3))]
    best = None
    for a0, b0 in starts:
        result = minimize(_nll, x0=[a0, b0, 0.01], args=(form, x, k, n, guess), method="L-BFGS-B", jac=True,
                          bounds=[(1e-9 * span, None), (1e-3 if form == "weibull" else 1e-6 * span, None),
                                  (0.0, max_lapse)])
        if best is None or result.fun < best.fun:
            best = result
    a, b, lapse = best.x
    return Fit(form, float(a), float(b), float(lapse), guess, -float(best.fun))


def bootstrap(result: Fit, levels: Sequence[float], trials: Sequence[int], samples: int = 200,
              seed: int = 1, confidence: float = 0.95) -> Tuple[float, float]:
    """The parametric bootstrap's percentile interval of the threshold."""
    rng = np.random.default_rng(seed)
    x = np.asarray(levels, dtype=float)
    n = np.asarray(trials, dtype=int)
    p = result.p(x)
    thresholds = []
    for _ in range(samples):
        k = rng.binomial(n, p)
        thresholds.append(fit(x, k, n, result.form, result.guess, start=result).threshold)
    lo, hi = np.quantile(thresholds, [(1 - confidence) / 2, (1 + confidence) / 2])
    return float(lo), float(hi)


def staircase_interval(reversal_levels: Sequence[float], confidence: float = 0.95) -> Optional[Tuple[float, float]]:
    """A t interval of the mean of a staircase's reversal levels (its threshold): a summary of
    their spread, not a calibrated interval (successive reversals are not independent)."""
    from scipy.stats import t as student

    r = np.asarray(reversal_levels, dtype=float)
    if r.size < 2:
        return None
    half = student.ppf((1 + confidence) / 2, r.size - 1) * r.std(ddof=1) / math.sqrt(r.size)
    return float(r.mean() - half), float(r.mean() + half)
