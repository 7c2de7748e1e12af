# SPDX-License-Identifier: Apache-2.0
"""Psychometric functions fitted by maximum likelihood (scipy), with bootstrap confidence
intervals and goodness of fit, for two-interval forced choice (guess rate 1/2) and other designs.

    P(correct | x) = guess + (1 - guess - lapse) * F(x)

F is a Weibull, 1 - exp(-(x / alpha)^beta) (x > 0), or a logistic, 1 / (1 + exp(-(x - alpha) /
beta)). The threshold is where F = 1/2 (75 % correct in 2IFC without lapses): alpha * ln(2)^(1 /
beta) for the Weibull, alpha for the logistic. The lapse rate is fitted in [0, max_lapse]
(Wichmann and Hill 2001a).

The likelihood of a few hundred answers has flat parts and, for non-monotonic data, several
maxima: a fit starts from a grid over (alpha, beta, lapse) covering the bounds and refines the
best separated grid points locally (L-BFGS-B), so it finds the global maximum within the bounds.
The bounds are wide (a threshold up to 100 times outside the tested levels); a fit that ends on
one, or whose threshold lies outside the tested levels, is flagged. Flags that say the data did
not determine the threshold (outside the levels, alpha at a bound, an interval the data cannot
support) exclude it from means across participants; a slope or lapse at a bound is a note: a
step between two levels is steeper than their spacing can resolve, yet it places the threshold
between them. The confidence interval is a parametric bootstrap's percentile interval
(Wichmann and Hill 2001b): new answers drawn from the fitted function at the same levels and
trial counts, each refitted by the same multi-start procedure. Goodness of fit is the deviance
compared with the deviances of those refits (Wichmann and Hill 2001a).

Wichmann, F. A. and Hill, N. J. (2001a). The psychometric function: I. Fitting, sampling, and
goodness of fit. Perception & Psychophysics 63(8), 1293-1313.
Wichmann, F. A. and Hill, N. J. (2001b). The psychometric function: II. Bootstrap-based
confidence intervals and sampling. Perception & Psychophysics 63(8), 1314-1329.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
from scipy.optimize import minimize

FORMS = ("weibull", "logistic")
FLAT = 0.01  # a log-likelihood this close to the maximum at a bound: the data do not bound the parameter
OUTSIDE_FACTOR = 100.0  # the bounds: alpha up to this many times (Weibull) or spans (logistic) past the levels


@dataclass
class Fit:
    form: str
    alpha: float
    beta: float
    lapse: float
    guess: float
    log_likelihood: float
    at_bound: List[str] = field(default_factory=list)  # "alpha (lower)", "beta (upper)", "lapse (upper)"

    def f(self, x):
        x = np.asarray(x, dtype=float)
        with np.errstate(over="ignore", under="ignore", divide="ignore"):
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

    @property
    def slope(self) -> float:
        """dP/dx at the threshold: F'(threshold) = beta ln 2 / (2 threshold) for the Weibull,
        1 / (4 beta) for the logistic, times (1 - guess - lapse)."""
        if self.form == "weibull":
            df = self.beta * math.log(2.0) / (2.0 * self.threshold)
        else:
            df = 1.0 / (4.0 * self.beta)
        return (1.0 - self.guess - self.lapse) * df


def deviance(fitted: Fit, levels, correct, trials) -> float:
    """2 sum(k ln(k / (n p)) + (n - k) ln((n - k) / (n (1 - p)))): the log-likelihood ratio of
    the saturated model (each level its own proportion) to the fit (Wichmann and Hill 2001a)."""
    k = np.asarray(correct, dtype=float)
    n = np.asarray(trials, dtype=float)
    p = np.clip(fitted.p(np.asarray(levels, dtype=float)), 1e-12, 1 - 1e-12)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(k > 0, k * np.log(k / (n * p)), 0.0)
        b = np.where(n - k > 0, (n - k) * np.log((n - k) / (n * (1 - p))), 0.0)
    return float(2.0 * np.sum(a + b))


def _bounds(form: str, x: np.ndarray, max_lapse: float) -> List[Tuple[float, float]]:
    """Bounds in the optimiser's coordinates: (ln alpha, ln beta, lapse) for the Weibull,
    (alpha, ln beta, lapse) for the logistic."""
    lo, hi = float(x.min()), float(x.max())
    if form == "weibull":
        return [(math.log(lo / OUTSIDE_FACTOR), math.log(hi * OUTSIDE_FACTOR)), (math.log(0.2), math.log(50.0)),
                (0.0, max_lapse)]
    span = (hi - lo) or 1.0
    return [(lo - OUTSIDE_FACTOR * span, hi + OUTSIDE_FACTOR * span), (math.log(span * 1e-3), math.log(span * 10.0)),
            (0.0, max_lapse)]


def _grid(form: str, x: np.ndarray, bounds) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid points: dense over the tested levels (and a little past them), sparse to the bounds."""
    lo, hi = float(x.min()), float(x.max())
    if form == "weibull":
        near = np.linspace(math.log(lo / 2), math.log(hi * 2), 28)
    else:
        span = (hi - lo) or 1.0
        near = np.linspace(lo - span / 2, hi + span / 2, 28)
    a = np.concatenate([np.linspace(bounds[0][0], near[0], 5)[:-1], near, np.linspace(near[-1], bounds[0][1], 5)[1:]])
    b = np.linspace(bounds[1][0], bounds[1][1], 24)
    lapse = np.linspace(bounds[2][0], bounds[2][1], 3)
    return a, b, lapse


def _f_and_grads(form, u0, u1, x):
    """F and its derivatives in the optimiser's coordinates (u0, u1) (broadcasting)."""
    with np.errstate(over="ignore", under="ignore", invalid="ignore", divide="ignore"):
        b = np.exp(u1)
        if form == "weibull":
            logr = np.log(np.maximum(x, 1e-300)) - u0  # ln(x / alpha)
            w = np.exp(np.minimum(b * logr, 700.0))  # (x / alpha)^beta
            e = np.exp(-w)
            return 1.0 - e, e * (-b * w), e * w * logr * b
        z = (x - u0) / b
        f = 1.0 / (1.0 + np.exp(-z))
        d = f * (1.0 - f)
        return f, d * (-1.0 / b), d * (-z)


def _nll(params, form, x, k, n, guess):
    """The negative log-likelihood and its gradient in the optimiser's coordinates."""
    u0, u1, lapse = params
    scale = 1.0 - guess - lapse
    f, df0, df1 = _f_and_grads(form, u0, u1, x)
    p = np.clip(guess + scale * f, 1e-12, 1.0 - 1e-12)
    nll = -float(np.sum(k * np.log(p) + (n - k) * np.log(1.0 - p)))
    dnll_dp = -(k / p - (n - k) / (1.0 - p))
    grad = np.nan_to_num(np.array([np.sum(dnll_dp * scale * df0), np.sum(dnll_dp * scale * df1),
                                   np.sum(dnll_dp * -f)]), nan=0.0, posinf=1e300, neginf=-1e300)
    return nll, grad


def _grid_nll(form, grid, x, k, n, guess) -> np.ndarray:
    a, b, lapse = grid
    f = _f_and_grads(form, a[:, None, None, None], b[None, :, None, None], x[None, None, None, :])[0]
    p = np.clip(guess + (1.0 - guess - lapse[None, None, :, None]) * f, 1e-12, 1.0 - 1e-12)
    return -np.sum(k * np.log(p) + (n - k) * np.log(1.0 - p), axis=-1)


def _starts(nll_grid: np.ndarray, grid, margin: float = 3.0, count: int = 4) -> List[Tuple[float, float, float]]:
    """The grid's local minima, best first, those within `margin` of the best: the maxima of
    non-monotonic data lie at different thresholds, or at one threshold with a shallow slope and
    no lapse and with a steeper one and lapses."""
    from scipy.ndimage import minimum_filter

    a, b, lapse = grid
    minima = np.argwhere(nll_grid <= minimum_filter(nll_grid, size=3, mode="nearest"))
    values = nll_grid[tuple(minima.T)]
    out = []
    for i, j, m in minima[np.argsort(values, kind="stable")][:count]:
        if nll_grid[i, j, m] > values.min() + margin:
            break
        out.append((float(a[i]), float(b[j]), float(lapse[m])))
    return out


def _at_bound_nll(params, index, end, bounds, profile, form, x, k, n, guess) -> float:
    """The negative log-likelihood with parameter `index` at `end`: the others held, or
    (profile) refitted."""
    moved = list(params)
    moved[index] = end
    if not profile:
        return _nll(moved, form, x, k, n, guess)[0]
    free = [i for i in range(3) if i != index]

    def partial(v):
        full = list(moved)
        for i, value in zip(free, v):
            full[i] = value
        value, grad = _nll(full, form, x, k, n, guess)
        return value, grad[free]

    return float(minimize(partial, x0=[moved[i] for i in free], method="L-BFGS-B", jac=True,
                          bounds=[bounds[i] for i in free]).fun)


def fit(levels: Sequence[float], correct: Sequence[int], trials: Sequence[int], form: str = "weibull",
        guess: float = 0.5, max_lapse: float = 0.06, start: Optional[Fit] = None, profile: bool = True) -> Fit:
    """The maximum-likelihood fit of answers counted per level: a grid over the bounds, then
    L-BFGS-B from the grid's best local minima (and from `start` too, if given). `profile`:
    check alpha and beta against their bounds by profile likelihood (else alpha only, held)."""
    if form not in FORMS:
        raise ValueError(f"form must be 'weibull' or 'logistic' (got {form!r})")
    x = np.asarray(levels, dtype=float)
    k = np.asarray(correct, dtype=float)
    n = np.asarray(trials, dtype=float)
    if form == "weibull" and np.any(x <= 0):
        raise ValueError("a Weibull needs levels > 0")
    bounds = _bounds(form, x, max_lapse)
    grid = _grid(form, x, bounds)
    starts = _starts(_grid_nll(form, grid, x, k, n, guess), grid)
    if start is not None and start.form == form:
        u0 = math.log(start.alpha) if form == "weibull" else start.alpha
        starts.append((u0, math.log(start.beta), start.lapse))
    best = None
    for s in starts:
        s = [min(max(v, lo), hi) for v, (lo, hi) in zip(s, bounds)]
        result = minimize(_nll, x0=s, args=(form, x, k, n, guess), method="L-BFGS-B", jac=True, bounds=bounds)
        if best is None or result.fun < best.fun:
            best = result
    u0, u1, lapse = (float(v) for v in best.x)
    at_bound = []
    for index, name in ((0, "alpha"), (1, "beta")):
        # On a bound, or as likely at the bound (within FLAT) as at the fit, the other parameters
        # refitted (profile likelihood): a step in the data, beta would grow without end; all
        # answers correct, alpha would shrink without end. The bootstrap's refits look at alpha
        # alone, the others held (cheaper; enough to see an interval's end on a bound).
        for side, end in (("lower", bounds[index][0]), ("upper", bounds[index][1])):
            if abs(best.x[index] - end) <= 1e-3 * (bounds[index][1] - bounds[index][0]) or \
                    (profile or index == 0) and _at_bound_nll(best.x, index, end, bounds, profile, form, x, k, n,
                                                              guess) <= best.fun + FLAT:
                at_bound.append(f"{name} ({side})")
                break
    if lapse >= max_lapse - 1e-6:
        # At 0 the lapse is where a lapse-free observer puts it; at its upper bound it absorbs
        # misfit and biases the slope and threshold (Wichmann and Hill 2001a).
        at_bound.append("lapse (upper)")
    alpha = math.exp(u0) if form == "weibull" else u0
    return Fit(form, alpha, math.exp(u1), lapse, guess, -float(best.fun), at_bound)


@dataclass
class BootstrapResult:
    thresholds: np.ndarray
    deviances: np.ndarray
    alpha_at_bound: np.ndarray  # per refit: its alpha ended on a bound
    confidence: float

    @property
    def interval(self) -> Tuple[float, float]:
        lo, hi = np.quantile(self.thresholds, [(1 - self.confidence) / 2, (1 + self.confidence) / 2])
        return float(lo), float(hi)


def bootstrap_refits(result: Fit, levels: Sequence[float], trials: Sequence[int], samples: int = 200,
                     seed: int = 1, confidence: float = 0.95, max_lapse: float = 0.06) -> BootstrapResult:
    """Parametric bootstrap: answers drawn from the fitted function, each set refitted by the
    same multi-start procedure as the fit."""
    rng = np.random.default_rng(seed)
    x = np.asarray(levels, dtype=float)
    n = np.asarray(trials, dtype=int)
    p = result.p(x)
    thresholds, deviances, at_bound = [], [], []
    for _ in range(samples):
        k = rng.binomial(n, p)
        refit = fit(x, k, n, result.form, result.guess, max_lapse, profile=False)
        thresholds.append(refit.threshold)
        deviances.append(deviance(refit, x, k, n))
        at_bound.append(any(b.startswith("alpha") for b in refit.at_bound))
    return BootstrapResult(np.array(thresholds), np.array(deviances), np.array(at_bound), confidence)


def bootstrap(result: Fit, levels: Sequence[float], trials: Sequence[int], samples: int = 200,
              seed: int = 1, confidence: float = 0.95) -> Tuple[float, float]:
    """The parametric bootstrap's percentile interval of the threshold."""
    return bootstrap_refits(result, levels, trials, samples, seed, confidence).interval


@dataclass
class Assessment:
    """A fit, its interval and goodness of fit, and what the data did not determine."""
    fit: Fit
    levels: Tuple[float, float]  # the lowest and the highest level tested
    interval: Tuple[float, float]
    deviance: float
    deviance_p: float  # the fraction of bootstrap deviances at least as large
    flags: List[str]  # everything the data did not determine, each with why
    threshold_flags: List[str] = field(default_factory=list)  # those of `flags` that undermine the threshold

    @property
    def flagged(self) -> bool:
        """The threshold is not determined by the data: left out of means across participants."""
        return bool(self.threshold_flags)

    @property
    def notes(self) -> List[str]:
        """Flags that leave the threshold determined: the slope or the lapse rate at a bound."""
        return [f for f in self.flags if f not in self.threshold_flags]

    def as_dict(self) -> Dict[str, object]:
        f = self.fit
        return {"form": f.form, "threshold": f.threshold, "ci_low": self.interval[0], "ci_high": self.interval[1],
                "alpha": f.alpha, "beta": f.beta, "lapse": f.lapse, "slope": f.slope,
                "log_likelihood": f.log_likelihood, "deviance": self.deviance, "deviance_p": self.deviance_p,
                "lowest_level": self.levels[0], "highest_level": self.levels[1], "flags": list(self.flags),
                "threshold_flags": list(self.threshold_flags)}


def assess(levels: Sequence[float], correct: Sequence[int], trials: Sequence[int], form: str = "weibull",
           guess: float = 0.5, max_lapse: float = 0.06, samples: int = 200, seed: int = 1,
           confidence: float = 0.95) -> Assessment:
    """Fit, bootstrap, and flag: a threshold outside the tested levels, a parameter at a bound
    (alpha, beta; lapse at its upper one), an interval of zero width or whose end is a bound
    (more than its tail's share of refits ended with alpha on a bound). All but beta and lapse
    are threshold flags: the data do not place the threshold. Beta at a bound (answers that jump
    between two levels, or barely rise) and the lapse at its upper bound bias the slope, yet the
    threshold inside the levels with an interval the data bound is still an estimate: they are
    notes."""
    x = np.asarray(levels, dtype=float)
    fitted = fit(x, correct, trials, form, guess, max_lapse)
    boot = bootstrap_refits(fitted, x, trials, samples, seed, confidence, max_lapse)
    lo, hi = boot.interval
    flags: List[str] = []
    threshold_flags: List[str] = []

    def flag(text: str, undermines_threshold: bool) -> None:
        flags.append(text)
        if undermines_threshold:
            threshold_flags.append(text)

    t = fitted.threshold
    if not float(x.min()) <= t <= float(x.max()):
        side = "below" if t < float(x.min()) else "above"
        flag(f"threshold {side} the tested levels [{float(x.min()):g}, {float(x.max()):g}]", True)
    for b in fitted.at_bound:
        name, side = b.rstrip(")").split(" (")
        steep = (side == "upper") == (form == "weibull")  # the Weibull's beta is a shape, the logistic's a scale
        why = {"alpha": "the threshold parameter: the data do not bound it",
               "beta": "the slope is not determined: " + ("steeper than the levels' spacing resolves" if steep
                                                          else "shallower than the levels' range resolves"),
               "lapse": "lapses absorb a misfit"}[name]
        flag(f"{name} at its {side} bound ({why})", name == "alpha")
    if hi - lo <= 1e-6 * max(abs(t), float(x.max())):
        flag("interval of zero width", True)
    elif boot.alpha_at_bound.mean() > (1 - confidence) / 2:
        flag(f"interval reaches a bound ({boot.alpha_at_bound.mean():.0%} of refits at one)", True)
    d = deviance(fitted, x, correct, trials)
    return Assessment(fitted, (float(x.min()), float(x.max())), (lo, hi), d, float(np.mean(boot.deviances >= d)),
                      flags, threshold_flags)


def staircase_interval(reversal_levels: Sequence[float], confidence: float = 0.95) -> Optional[Tuple[float, float]]:
    """A t interval of the mean of a staircase's reversal levels (its threshold): a summary of
    their spread, not a calibrated interval (successive reversals are not independent)."""
    from scipy.stats import t as student

    r = np.asarray(reversal_levels, dtype=float)
    if r.size < 2:
        return None
    half = student.ppf((1 + confidence) / 2, r.size - 1) * r.std(ddof=1) / math.sqrt(r.size)
    return float(r.mean() - half), float(r.mean() + half)
