# SPDX-License-Identifier: Apache-2.0
"""Simulated participants: model observers of two-interval forced choice on a physical quantity
of the simulated device's trace, with a known threshold, so that the tests can check
that the procedures and the fits find it.

The observer perceives each interval's quantity q with independent Gaussian noise of standard
deviation `noise` and names the interval whose perceived q is larger; with probability `lapse`
it does not attend and guesses. So

    P(correct | q_test - q_ref = d) = lapse / 2 + (1 - lapse) * Phi(d / (noise * sqrt 2))

and its threshold (F = 1/2 in psychometric.py's form, 75 % correct without lapses) is the
quantity difference d* = noise * sqrt 2 * Phi^-1(3/4), or in stimulus units the level whose
quantity difference is d*. Every answer is drawn from a generator seeded by (seed, block,
trial), so a resumed session gets the answers an uninterrupted one would.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass
from typing import Callable, Dict, Sequence

import numpy as np
from scipy.stats import norm

Z75 = float(norm.ppf(0.75))  # Phi^-1(3/4)


@dataclass
class ModelObserver:
    noise: float  # standard deviation of the perceived quantity, in its unit
    lapse: float = 0.0
    seed: int = 1

    def answer(self, q_reference: float, q_test: float, block: int, trial: int) -> bool:
        """Whether it names the test interval (the correct answer)."""
        rng = random.Random(f"{self.seed}/{block}/{trial}")
        if rng.random() < self.lapse:
            return rng.random() < 0.5
        return q_test + rng.gauss(0.0, self.noise) > q_reference + rng.gauss(0.0, self.noise)

    @property
    def threshold_difference(self) -> float:
        return self.noise * math.sqrt(2.0) * Z75

    def p_correct(self, difference: float) -> float:
        return self.lapse / 2 + (1 - self.lapse) * float(norm.cdf(difference / (self.noise * math.sqrt(2.0))))


def observer_for_threshold(threshold_level: float, quantity: Callable[[float], float], reference_quantity: float,
                           lapse: float = 0.0, seed: int = 1) -> ModelObserver:
    """The observer whose threshold is `threshold_level` on a stimulus whose quantity is
    `quantity(level)` against a reference of `reference_quantity`."""
    d = quantity(threshold_level) - reference_quantity
    if d <= 0:
        raise ValueError("the quantity must grow from the reference to the threshold level")
    return ModelObserver(noise=d / (math.sqrt(2.0) * Z75), lapse=lapse, seed=seed)


def threshold_level(observer: ModelObserver, levels: Sequence[float], quantities: Sequence[float],
                    reference_quantity: float) -> float:
    """The stimulus level of the observer's threshold, by linear interpolation of the quantity
    measured at `levels` (ascending, the quantity growing with them)."""
    d = np.asarray(quantities, dtype=float) - reference_quantity
    return float(np.interp(observer.threshold_difference, d, np.asarray(levels, dtype=float)))


class QuantityCache:
    """A stimulus level's quantity, measured once per level (the simulation is deterministic:
    the same level gives the same trace)."""

    def __init__(self, measure: Callable[[float], float]):
        self._measure = measure
        self._cache: Dict[float, float] = {}

    def __call__(self, level: float) -> float:
        key = float(level)
        if key not in self._cache:
            self._cache[key] = float(self._measure(key))
        return self._cache[key]
