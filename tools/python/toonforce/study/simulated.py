"""A simulated participant playing a session on the simulated device (issue 31): each interval
is a closed-loop run of the condition's scene (the level set at its `vary` key) with the
experiment's hand script, through `toonforce.sim` (the real servo loop); the model observer
(observer.py) perceives the experiment's quantity of each trace and answers."""

from __future__ import annotations

from typing import Any, Dict, Optional

from . import experiment as experiments
from .observer import ModelObserver, QuantityCache, observer_for_threshold
from .session import scene_with


class SimulatedParticipant:
    def __init__(self, exp: experiments.Experiment, observer: ModelObserver):
        self.experiment = exp
        self.observer = observer
        self._quantities: Dict[Any, QuantityCache] = {}

    @staticmethod
    def with_threshold(exp: experiments.Experiment, block: experiments.Block, threshold: float, lapse: float = 0.0,
                       seed: int = 1) -> "SimulatedParticipant":
        """An observer whose threshold on `block`'s test condition is `threshold` (its level)."""
        participant = SimulatedParticipant(exp, ModelObserver(1.0))
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

    def __call__(self, block: experiments.Block, index: int, trial: int, level: float,
                 test_first: bool) -> Dict[str, Any]:
        q_ref = self.reference_quantity(block)
        q_test = self.quantity(block.test)(level)
        correct = self.observer.answer(q_ref, q_test, index, trial)
        chose = (1 if test_first else 2) if correct else (2 if test_first else 1)
        return {"correct": correct, "answer": chose, "q_reference": q_ref, "q_test": q_test}
