# SPDX-License-Identifier: Apache-2.0
"""The report's tests: the Wilcoxon signed-rank test with its method stated, the sign test, and
the effect size beside each p-value.

The Wilcoxon signed-rank test (Wilcoxon 1945; Hollander, Wolfe and Chicken 2014, ch. 3) takes
the options of scipy.stats.wilcoxon and gives the same statistic and p-value for them:
zero_method "wilcox" (zero differences dropped before ranking), "pratt" (ranked, then dropped:
Pratt 1959) or "zsplit" (their ranks split between the two signs); method "approx" (the normal
approximation, its variance corrected for ties, Pratt's zeros as in Cureton 1967, with a
continuity correction if `correction`) or "exact". scipy's exact method (1.10) assumes no zeros
and no ties; here "exact" is the exact distribution of the signed-rank sum given the observed
ranks, midranks and zeros included (every assignment of signs to the non-zero differences
equally likely under the null hypothesis: the conditional test of Hollander, Wolfe and Chicken),
which is scipy's exact distribution when there are neither. The two-sided p-value doubles the
smaller tail, as scipy does.

Effect sizes: the matched-pairs rank-biserial correlation r = (R+ - R-) / (R+ + R-), from -1 to
1 (Kerby 2014), beside a Wilcoxon test; Cohen's g = (proportion of one sign) - 1/2 beside a sign
or binomial test (Cohen 1988).

Wilcoxon, F. (1945). Individual comparisons by ranking methods. Biometrics Bulletin 1(6), 80-83.
Pratt, J. W. (1959). Remarks on zeros and ties in the Wilcoxon signed rank procedures. Journal of
the American Statistical Association 54, 655-667.
Cureton, E. E. (1967). The normal approximation to the signed-rank sampling distribution when
zero differences are present. Journal of the American Statistical Association 62, 1068-1069.
Hollander, M., Wolfe, D. A. and Chicken, E. (2014). Nonparametric Statistical Methods, 3rd ed. Wiley.
Kerby, D. S. (2014). The simple difference formula: an approach to teaching nonparametric
correlation. Comprehensive Psychology 3, 11.IT.3.1.
Cohen, J. (1988). Statistical Power Analysis for the Behavioral Sciences, 2nd ed. Erlbaum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.stats import binomtest, norm, rankdata


@dataclass
class TestResult:
    name: str  # the test and how it was computed, for the report
    statistic: float
    pvalue: float
    effect: float
    effect_name: str
    n: int  # the observations the test used (participants, or answers)

    def text(self) -> str:
        return (f"{self.name}: statistic {self.statistic:g}, p = {self.pvalue:.3g}, "
                f"{self.effect_name} {self.effect:+.2f} (n = {self.n})")


def _exact_two_sided(ranks: np.ndarray, r_plus: float) -> float:
    """P-value from the exact null distribution of the sum of the ranks given a + sign, each of
    the 2^n sign assignments equally likely; ranks are multiples of 1/2 (midranks), so the
    distribution is counted on doubled ranks by dynamic programming."""
    doubled = np.rint(2 * ranks).astype(int)
    counts = np.zeros(int(doubled.sum()) + 1)
    counts[0] = 1.0
    for r in doubled:
        shifted = np.zeros_like(counts)
        shifted[r:] = counts[:counts.size - r]
        counts = counts + shifted
    pmf = counts / counts.sum()
    t = int(round(2 * r_plus))
    p_less, p_greater = pmf[:t + 1].sum(), pmf[t:].sum()
    return float(min(1.0, 2 * min(p_less, p_greater)))


def wilcoxon(d: Sequence[float], zero_method: str = "wilcox", correction: bool = False,
             method: str = "auto") -> TestResult:
    """Two-sided signed-rank test of differences `d` (see the module's text). "auto": exact if
    at most 50 differences remain after zeros are dropped, else the normal approximation."""
    d = np.asarray(d, dtype=float)
    if zero_method not in ("wilcox", "pratt", "zsplit"):
        raise ValueError("zero_method must be 'wilcox', 'pratt' or 'zsplit'")
    if zero_method == "wilcox":
        d = d[d != 0]
    zeros = int(np.sum(d == 0))
    if d.size == 0 or zeros == d.size:
        raise ValueError("every difference is zero")
    if method == "auto":
        method = "exact" if np.count_nonzero(d) <= 50 else "approx"
    if method not in ("exact", "approx"):
        raise ValueError("method must be 'auto', 'exact' or 'approx'")
    r = rankdata(np.abs(d))
    r_plus, r_minus = float(np.sum(r[d > 0])), float(np.sum(r[d < 0]))
    if zero_method == "zsplit":
        r_zero = float(np.sum(r[d == 0]))
        r_plus, r_minus = r_plus + r_zero / 2, r_minus + r_zero / 2
    t = min(r_plus, r_minus)
    ties = len(np.unique(r[d != 0])) < np.count_nonzero(d)
    if method == "exact":
        # The zero differences' ranks (zsplit) add the same half to either sum.
        shift = float(np.sum(r[d == 0])) / 2 if zero_method == "zsplit" else 0.0
        p = _exact_two_sided(r[d != 0], r_plus - shift)
        how = ("exact (the conditional distribution given the midranks and zeros)" if ties or zeros
               else "exact")
    else:
        count = d.size
        mean = count * (count + 1) / 4
        var = count * (count + 1) * (2 * count + 1)
        ranks = r
        if zero_method == "pratt":
            ranks = r[d != 0]
            mean -= zeros * (zeros + 1) / 4
            var -= zeros * (zeros + 1) * (2 * zeros + 1)
        _, repeats = np.unique(ranks, return_counts=True)
        var -= 0.5 * float(np.sum(repeats * (repeats * repeats - 1)))
        se = math.sqrt(var / 24)
        c = 0.5 * np.sign(t - mean) if correction else 0.0
        z = (t - mean - c) / se
        p = float(2 * norm.sf(abs(z)))
        how = f"normal approximation ({'with' if correction else 'without'} continuity correction, ties corrected)"
    total = r_plus + r_minus
    effect = (r_plus - r_minus) / total if total > 0 else 0.0
    name = f"Wilcoxon signed-rank, {how}, zero_method={zero_method}"
    return TestResult(name, t, p, effect, "rank-biserial r", int(np.count_nonzero(d)))


def sign_test(d: Sequence[float]) -> TestResult:
    """Two-sided exact binomial test of the count of positive differences among the non-zero
    ones against 1/2; Cohen's g beside it."""
    d = np.asarray(d, dtype=float)
    plus, n = int(np.sum(d > 0)), int(np.count_nonzero(d))
    if n == 0:
        raise ValueError("every difference is zero")
    return TestResult("sign test, exact binomial (zeros dropped)", plus, float(binomtest(plus, n, 0.5).pvalue),
                      plus / n - 0.5, "Cohen's g", n)


def binomial(successes: int, n: int) -> TestResult:
    """Two-sided exact binomial test against 1/2 (one participant's answers); Cohen's g."""
    return TestResult("binomial, exact", successes, float(binomtest(successes, n, 0.5).pvalue), successes / n - 0.5,
                      "Cohen's g", n)
