# SPDX-License-Identifier: Apache-2.0
"""The psychophysical procedures of a study block, as state machines that take one
answer at a time: `next_level()` says what to present, `record(correct)` takes the answer. Each
is rebuilt exactly by replaying its recorded answers (a resumed session goes on where it was).

- TransformedStaircase: Levitt's transformed up-down (1971): `down` correct answers in a row
  step down, `up` wrong ones step up; 1-up-2-down converges on 70.7 % correct, 1-up-3-down on
  79.4 %.
- WeightedStaircase: Kaernbach's weighted up-down (1991): one step down after each correct
  answer, `target / (1 - target)` steps up after each wrong one; converges on `target`.
- ConstantStimuli: every level `repetitions` times, in an order shuffled from the session's seed.

A staircase's threshold is the mean of the levels at its last reversals (the first `discard`
reversals left out), as Levitt recommends; it stops after `reversals` reversals or
`max_trials` trials.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import List, Optional, Sequence


@dataclass
class _Staircase:
    start: float
    step: float
    minimum: float
    maximum: float
    reversals: int = 12
    discard: int = 4
    max_trials: int = 200
    levels: List[float] = field(default_factory=list)  # presented, in order
    answers: List[bool] = field(default_factory=list)
    reversal_levels: List[float] = field(default_factory=list)
    _level: float = 0.0
    _direction: int = 0  # -1 going down, +1 going up, 0 not yet moved

    def __post_init__(self) -> None:
        if not self.minimum <= self.start <= self.maximum:
            raise ValueError(f"start {self.start:g} outside [{self.minimum:g}, {self.maximum:g}]")
        if self.step <= 0:
            raise ValueError(f"step must be > 0 (got {self.step:g})")
        if not 0 <= self.discard < self.reversals:
            raise ValueError(f"discard ({self.discard}) must be below reversals ({self.reversals})")
        self._level = self.start

    @property
    def done(self) -> bool:
        return len(self.reversal_levels) >= self.reversals or len(self.answers) >= self.max_trials

    def next_level(self) -> float:
        return self._level

    def _move(self, direction: int, size: float) -> None:
        if self._direction != 0 and direction != self._direction:
            self.reversal_levels.append(self._level)
        self._direction = direction
        self._level = min(self.maximum, max(self.minimum, self._level + direction * size))

    def threshold(self) -> Optional[float]:
        """Mean level at the reversals after the first `discard` (None before any)."""
        kept = self.reversal_levels[self.discard:]
        return sum(kept) / len(kept) if kept else None


@dataclass
class TransformedStaircase(_Staircase):
    down: int = 2
    up: int = 1
    _run: int = 0  # correct (>0) or wrong (<0) answers in a row

    def record(self, correct: bool) -> None:
        self.levels.append(self._level)
        self.answers.append(bool(correct))
        if correct:
            self._run = self._run + 1 if self._run > 0 else 1
            if self._run >= self.down:
                self._run = 0
                self._move(-1, self.step)
        else:
            self._run = self._run - 1 if self._run < 0 else -1
            if -self._run >= self.up:
                self._run = 0
                self._move(+1, self.step)

    @property
    def target(self) -> float:
        """The proportion correct it converges on: p^down = 1/2 for 1-up (Levitt)."""
        return 0.5 ** (1.0 / self.down) if self.up == 1 else float("nan")


@dataclass
class WeightedStaircase(_Staircase):
    target: float = 0.75

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 0.5 <= self.target < 1.0:
            raise ValueError(f"target must be in [0.5, 1) (got {self.target:g})")

    def record(self, correct: bool) -> None:
        self.levels.append(self._level)
        self.answers.append(bool(correct))
        if correct:
            self._move(-1, self.step)
        else:
            self._move(+1, self.step * self.target / (1.0 - self.target))


@dataclass
class ConstantStimuli:
    stimuli: Sequence[float]
    repetitions: int
    seed: int
    levels: List[float] = field(default_factory=list)
    answers: List[bool] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.stimuli or self.repetitions < 1:
            raise ValueError("constant stimuli need at least one level and one repetition")
        order = [float(s) for s in self.stimuli for _ in range(self.repetitions)]
        random.Random(self.seed).shuffle(order)
        self._order = order

    @property
    def done(self) -> bool:
        return len(self.answers) >= len(self._order)

    def next_level(self) -> float:
        return self._order[len(self.answers)]

    def record(self, correct: bool) -> None:
        self.levels.append(self.next_level())
        self.answers.append(bool(correct))

    def counts(self):
        """(levels, correct, trials), one entry per level, levels ascending."""
        levels = sorted(set(self.levels))
        correct = [sum(1 for l, a in zip(self.levels, self.answers) if l == level and a) for level in levels]
        trials = [sum(1 for l in self.levels if l == level) for level in levels]
        return levels, correct, trials


@dataclass
class FixedTrials:
    """A block whose trials are known in advance (ratings, paired comparisons): `trials` in an
    order shuffled from the session's seed; `record` keeps each trial's result."""

    trials: Sequence[dict]
    seed: int
    results: List[dict] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.trials:
            raise ValueError("a block needs at least one trial")
        order = [dict(t) for t in self.trials]
        random.Random(self.seed).shuffle(order)
        self._order = order

    @property
    def done(self) -> bool:
        return len(self.results) >= len(self._order)

    @property
    def answers(self) -> List[dict]:
        return self.results

    def next_trial(self) -> dict:
        return self._order[len(self.results)]

    def record(self, result: dict) -> None:
        self.results.append(dict(result))


def rating_trials(conditions: Sequence[str], repetitions: int) -> List[dict]:
    """Each condition `repetitions` times, rated on every item after it."""
    return [{"condition": c} for c in conditions for _ in range(repetitions)]


def pair_trials(pairs: Sequence[Sequence[str]], repetitions: int) -> List[dict]:
    """Each pair in both orders, `repetitions` times: order effects cancel."""
    return [{"first": a, "second": b} for a, b in pairs for _ in range(repetitions)] + \
           [{"first": b, "second": a} for a, b in pairs for _ in range(repetitions)]
