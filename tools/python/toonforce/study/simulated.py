# SPDX-License-Identifier: Apache-2.0
"""A simulated participant playing a session on the simulated device: each interval
is a closed-loop run of the condition's scene (the level set at its `vary` key) with the
experiment's hand script, through `toonforce.sim` (the real servo loop); the model observer
(observer.py) perceives the experiment's quantity of each trace and answers."""

from __future__ import annotations

import random
from typing import Any, Dict, Optional

from . import experiment as experiments
from .observer import ModelObserver, QuantityCache, observer_for_threshold
from .session import scene_with


class SimulatedParticipant:
    def __init__(self, exp: experiments.Experiment, observer: ModelObserver, rating_gain: float = 10.0):
        self.experiment = exp
        self.observer = observer
        self.rating_gain = rating_gain  # scale points per unit of the quantity (10 per N)
        self._quantities: Dict[Any, QuantityCache] = {}

    @staticmethod
    def with_threshold(exp: experiments.Experiment, block: experiments.Block, threshold: float, lapse: float = 0.0,
                       seed: int = 1) -> "SimulatedParticipant":
        """An observer whose threshold on `block`'s test condition is `threshold` (its level)."""
        participant = SimulatedParticipant(exp, ModelObserver(1.0))
        if block.procedure not in experiments.LEVEL_PROCEDURES:
            raise ValueError(f"block '{block.name}' has no level: a threshold is given on a level procedure's block")
        quantity = participant.quantity(block.test)
        participant.observer = observer_for_threshold(threshold, quantity, participant.reference_quantity(block),
                                                      lapse, seed)
        return participant

    def quantity(self, condition: str) -> QuantityCache:
        if condition not in self._quantities:
            import toonforce

            c = self.experiment.conditions[condition]
            measure = experiments.QUANTITIES[self.experiment.quantity]
            self._quantities[condition] = QuantityCache(
                lambda level: measure(toonforce.sim(scene_with(c, level if c.vary else None), self.experiment.script)))
        return self._quantities[condition]

    def reference_quantity(self, block: experiments.Block) -> float:
        return self.quantity(block.reference)(0.0)

    def two_interval(self, block: experiments.Block, index: int, trial: int, level: float,
                     test_first: bool) -> Dict[str, Any]:
        q_ref = self.reference_quantity(block)
        q_test = self.quantity(block.test)(level)
        correct = self.observer.answer(q_ref, q_test, index, trial)
        chose = (1 if test_first else 2) if correct else (2 if test_first else 1)
        return {"correct": correct, "answer": chose, "q_reference": q_ref, "q_test": q_test}

    __call__ = two_interval

    def fixed_quantity(self, condition: str) -> float:
        """The quantity of a condition's scene as it is (its overrides, no level)."""
        key = ("fixed", condition)
        if key not in self._quantities:
            import toonforce

            c = self.experiment.conditions[condition]
            measure = experiments.QUANTITIES[self.experiment.quantity]
            self._quantities[key] = measure(toonforce.sim(scene_with(c, None), self.experiment.script))
        return self._quantities[key]

    def _perceived(self, condition: str, index: int, trial: int, salt: str) -> float:
        q = self.fixed_quantity(condition)
        rng = random.Random(f"{self.observer.seed}/{index}/{trial}/{salt}")
        return q + rng.gauss(0.0, self.observer.noise)

    def rate(self, block: experiments.Block, index: int, trial: int, condition: str) -> Dict[str, Any]:
        """Each item rated from the perceived quantity: the scale's middle at zero, one point per
        `rating_gain` of quantity (its unit), rounded and held to the scale."""
        ratings = {}
        for item in block.options["items"]:
            points = item["points"]
            value = (points + 1) / 2 + self._perceived(condition, index, trial, item["name"]) * self.rating_gain
            ratings[item["name"]] = int(min(points, max(1, round(value))))
        return {"ratings": ratings}

    def perform(self, block: experiments.Block, index: int, trial: int, condition: str) -> Dict[str, Any]:
        """The task by the block's hand script on the condition's scene: a scripted hand, so every
        repetition is the same run (the simulation is deterministic)."""
        import toonforce

        c = self.experiment.conditions[condition]
        trace = toonforce.sim(scene_with(c, None), block.options.get("script", self.experiment.script))
        return {"metrics": experiments.task_metrics(block.options["task"], trace, block.options)}

    def compare(self, block: experiments.Block, index: int, trial: int, first: str, second: str) -> Dict[str, Any]:
        """Names the interval whose perceived quantity is larger (1 or 2)."""
        a = self._perceived(first, index, trial, "first")
        b = self._perceived(second, index, trial, "second")
        return {"chose": 1 if a > b else 2}
