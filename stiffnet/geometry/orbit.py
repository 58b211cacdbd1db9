"""Which orbit the record is on: ``n`` impacts every ``m`` forcing periods.

The paper's geometric method (section 5) and its Table 1 are for the period-1
orbit, one impact per forcing period (Fig. 9). The same rig also settles on
other orbits: from beta = 35 on, the paper's parameters started from rest end on
an orbit with two impacts every three periods. On such an orbit the free flight
before each impact is at another phase of the forcing, so the "before"
inclination reads the orbit, not beta: on simulate_paper's rest branch it falls
from ~88 deg (period-1, beta 35-60) to ~61 deg and no longer rises with beta.
The estimate therefore names the orbit it saw (:func:`impact_pattern`) and
says when it is not the one its calibration and Table 1 describe.

An ``(n, m)`` pattern is the smallest ``m`` (forcing periods) after which the
impact sequence repeats: impact ``i + n`` falls ``m`` periods after impact ``i``
for most ``i``, with ``n`` the number of impacts seen per ``m`` periods. A
chaotic or irregular sequence has no pattern up to :data:`MAX_PERIODS`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

#: Longest repeat searched, forcing periods.
MAX_PERIODS = 4
#: Impact ``i + n`` must be within this fraction of a period of ``m`` periods later ...
TOLERANCE = 0.1
#: ... for at least this fraction of the impacts.
AGREEMENT = 0.8


def impact_pattern(
    impacts: ArrayLike, period: float, max_periods: int = MAX_PERIODS
) -> tuple[int, int] | None:
    """``(n, m)``: the record shows ``n`` impacts every ``m`` forcing periods.

    Parameters
    ----------
    impacts : array_like of int
        Sample indices of the impacts, increasing.
    period : float
        Forcing period, samples.
    max_periods : int
        Longest repeat tried.

    Returns
    -------
    tuple of int or None
        ``(1, 1)`` for the period-1 orbit, ``(2, 3)`` for two impacts every three
        periods, ``(1, 2)`` for one impact every other period; None with fewer
        than three impacts or no repeat within `max_periods`.
    """
    t = np.asarray(impacts, dtype=np.float64)
    if t.size < 3 or not period > 0:
        return None
    rate = (t.size - 1) / ((t[-1] - t[0]) / period)  # impacts per forcing period
    for m in range(1, max_periods + 1):
        n = int(round(rate * m))
        if n < 1 or n >= t.size:
            continue
        lag = t[n:] - t[:-n]
        if np.mean(np.abs(lag / period - m) < TOLERANCE) >= AGREEMENT:
            return n, m
    return None


def describe_pattern(pattern: tuple[int, int] | None) -> str:
    """Words for an impact pattern (``"1 impact per forcing period"``, ...)."""
    if pattern is None:
        return "no repeating impact pattern within 4 forcing periods"
    n, m = pattern
    if m == 1:
        return f"{n} impact{'s' if n > 1 else ''} per forcing period"
    return f"{n} impact{'s' if n > 1 else ''} every {m} forcing periods"
