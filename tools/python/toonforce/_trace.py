# SPDX-License-Identifier: Apache-2.0
"""Traces as numpy arrays: one array per column, named as the command line's CSV columns."""
from __future__ import annotations

from typing import Dict, Iterator, List, Mapping

import numpy as np


class Trace(Mapping[str, np.ndarray]):
    """A trace: ``trace["fx"]`` is the column ``fx`` of the CSV ``toonforce`` writes, as a float64
    array holding the same doubles (the CSV prints each in shortest round-trip form).

    ``units[name]`` is the column's SI unit ("" for flags, bit sets, states and counts; "1" for
    ratios). ``summary`` holds what the command prints at the end, ``warnings`` what it would
    print on standard error. A Mapping: ``list(trace)`` is the columns in CSV order.
    """

    def __init__(self, columns: Dict[str, np.ndarray], units: Dict[str, str], summary: Dict[str, object],
                 warnings: List[str]) -> None:
        self._columns = columns
        self.units: Dict[str, str] = units
        self.summary: Dict[str, object] = summary
        self.warnings: List[str] = warnings

    def __getitem__(self, name: str) -> np.ndarray:
        return self._columns[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._columns)

    def __len__(self) -> int:
        return len(self._columns)

    @property
    def names(self) -> List[str]:
        """The columns, in the CSV's order."""
        return list(self._columns)

    @property
    def rows(self) -> int:
        """How many rows (ticks) the trace has."""
        first = next(iter(self._columns.values()), None)
        return 0 if first is None else int(first.shape[0])

    def to_structured(self) -> np.ndarray:
        """The trace as one structured array (a copy): ``a["fx"][k]``, ``a[k]["t"]``."""
        return np.rec.fromarrays(list(self._columns.values()), names=list(self._columns)).view(np.ndarray)

    def __repr__(self) -> str:
        return f"<toonforce.Trace {self.rows} rows x {len(self._columns)} columns>"
