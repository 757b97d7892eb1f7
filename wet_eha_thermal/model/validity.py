"""
Record where a correlation is used outside the range its source validates.

Correlations never extrapolate silently: each takes an optional
:class:`ValidityLog` and flags every evaluation that falls outside its stated
range. The model keeps one log per run, so a user (or the estimator's
diagnostics) can see which correlations ran out of range, how often, and the
extreme value seen.
"""

from dataclasses import dataclass
from typing import Dict, Iterator, Optional

import numpy as np

from .compiled import jit


@dataclass
class RangeFlag:
    """One correlation input seen outside its validated range."""

    correlation: str
    quantity: str
    low: float
    high: float
    note: str
    count: int = 0
    min_seen: float = np.inf
    max_seen: float = -np.inf

    def __str__(self) -> str:
        """Summarise the flag in one line a user can act on."""
        return (f'{self.correlation}: {self.quantity} seen in '
                f'[{self.min_seen:.4g}, {self.max_seen:.4g}], validated for '
                f'[{self.low:.4g}, {self.high:.4g}] ({self.count} evaluations); '
                f'{self.note}')


class ValidityLog:
    """Collects out-of-range uses of correlations, keyed by correlation and quantity."""

    def __init__(self) -> None:
        self._flags: Dict[tuple, RangeFlag] = {}

    def check(self, correlation: str, quantity: str, value, low: float, high: float,
              note: str = '') -> None:
        """Flag the values of ``value`` (scalar or array) outside ``[low, high]``."""
        arr = np.asarray(value, dtype=float)
        # the common case (all in range) costs one compiled pass; NaN marks a value
        # the correlation did not use, and is never flagged
        if within(arr.ravel(), float(low), float(high)):
            return
        outside = (arr < low) | (arr > high)
        if not np.any(outside):
            return
        key = (correlation, quantity)
        flag = self._flags.get(key)
        if flag is None:
            flag = self._flags[key] = RangeFlag(correlation, quantity, low, high, note)
        bad = arr[outside]
        flag.count += int(bad.size)
        flag.min_seen = min(flag.min_seen, float(bad.min()))
        flag.max_seen = max(flag.max_seen, float(bad.max()))

    def __iter__(self) -> Iterator[RangeFlag]:
        """Iterate over the flags raised so far."""
        return iter(self._flags.values())

    def __len__(self) -> int:
        """Return the number of distinct (correlation, quantity) flags."""
        return len(self._flags)

    def clear(self) -> None:
        """Forget all flags."""
        self._flags.clear()


def check(log: Optional[ValidityLog], correlation: str, quantity: str, value,
          low: float, high: float, note: str = '') -> None:
    """Flag out-of-range values into ``log`` when a log is given."""
    if log is not None:
        log.check(correlation, quantity, value, low, high, note)


@jit
def within(values, low, high):
    """Tell whether no value of the 1-D array ``values`` is below ``low`` or above ``high``."""
    for v in values:
        if v < low or v > high:
            return False
    return True
