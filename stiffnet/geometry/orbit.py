"""Which orbit the record is on, and where each impact sits in it.

The paper's geometric method (section 5) and its Table 1 are for the period-1
orbit, one impact per forcing period (Fig. 9). The same rig also settles on
other orbits: from beta = 35 on, the paper's parameters started from rest end on
an orbit with two impacts every three periods. The "before" inclination is the
slope of the approach just before an impact (z) over the slope ``2 tau`` earlier
(x), i.e. about ``|v(t_impact)| / |v(t_impact - 2 tau)|`` of the free flight. On
the period-1 branch the approach slope barely changes with beta (0.04-0.05 in
standardised units, beta 12-80) and the rising Table-1 trend comes from the
x-slope falling (0.009 -> 0.0045) as the impact phase moves; on the other orbit
the point ``2 tau`` back sits at another phase of the free flight (x-slope
0.019-0.027) and the angle falls from ~88 to ~56-65 deg at the same beta. No
phase-free rewriting of "before" keeps the trend (against the record's RMS
free-flight x-slope instead of each impact's own it is flat or falling on
period-1, 46-56 deg): the angle reads the orbit. So the estimate

* names the orbit (:func:`impact_pattern`) and calibrates period-1 windows and
  the others separately (:meth:`stiffnet.geometry.calibration.GeometricCalibration.for_orbit`);
* groups the per-impact inclinations by the impact's position in the orbit, the
  free flight that precedes it in forcing periods (:func:`flight_periods`,
  :func:`position_groups`), so a report shows each kind of impact on its own
  (beta 47 from rest, 2 every 3: ~65 deg after the 0.83-period flight, ~57 deg
  after the 2.17-period one).

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


def is_period1(pattern: tuple[int, int] | None) -> bool:
    """Whether `pattern` is the period-1 orbit the paper's calibration and Table 1 describe."""
    return pattern is not None and tuple(pattern) == (1, 1)


def flight_periods(at: ArrayLike, impacts: ArrayLike, period: float) -> np.ndarray:
    """Free flight before each impact in `at`: the interval from the previous detected impact.

    Parameters
    ----------
    at : array_like of int
        Sample indices near the impacts whose flight is wanted (e.g. where the
        orbits' impact regions start); each is matched to the nearest detected
        impact.
    impacts : array_like of int
        All detected impacts, increasing.
    period : float
        Forcing period, samples.

    Returns
    -------
    numpy.ndarray
        Forcing periods between the matched impact and the one before it; NaN
        for the first impact or where no detected impact lies within a quarter
        period of `at`.
    """
    t = np.asarray(impacts, dtype=np.float64)
    q = np.asarray(at, dtype=np.float64)
    out = np.full(q.shape, np.nan)
    if t.size < 2 or not period > 0:
        return out
    k = np.clip(np.searchsorted(t, q), 1, t.size - 1)
    k = np.where(np.abs(t[k - 1] - q) < np.abs(t[k] - q), k - 1, k)  # nearest impact
    ok = (k >= 1) & (np.abs(t[k] - q) <= 0.25 * period)
    out[ok] = (t[k[ok]] - t[k[ok] - 1]) / period
    return out


def position_groups(flights: ArrayLike, tolerance: float = TOLERANCE) -> np.ndarray:
    """Group impacts by their position in the orbit: flights within `tolerance` periods.

    Sorted flight times are cut wherever two neighbours differ by more than
    `tolerance` forcing periods; group 0 holds the shortest flights.

    Returns
    -------
    numpy.ndarray
        Int label per impact; -1 where the flight is unknown (NaN).
    """
    f = np.asarray(flights, dtype=np.float64)
    labels = np.full(f.shape, -1, dtype=np.int64)
    ok = np.flatnonzero(np.isfinite(f))
    if ok.size == 0:
        return labels
    order = ok[np.argsort(f[ok], kind="stable")]
    labels[order] = np.concatenate(([0], np.cumsum(np.diff(f[order]) > tolerance)))
    return labels


def position_summary(
    flights: ArrayLike, before_deg: ArrayLike, after_deg: ArrayLike
) -> list[dict[str, float]]:
    """Inclinations by position in the orbit (:func:`position_groups`), shortest flight first.

    Returns
    -------
    list of dict
        ``flight_periods`` (median), ``impacts``, ``before_deg`` and
        ``after_deg`` (means) per group; impacts without a known flight are left out.
    """
    f = np.asarray(flights, dtype=np.float64)
    b = np.asarray(before_deg, dtype=np.float64)
    a = np.asarray(after_deg, dtype=np.float64)
    labels = position_groups(f)
    out = []
    for g in range(int(labels.max()) + 1 if labels.size else 0):
        sel = labels == g
        out.append(
            {
                "flight_periods": float(np.median(f[sel])),
                "impacts": int(sel.sum()),
                "before_deg": float(np.mean(b[sel])),
                "after_deg": float(np.mean(a[sel])),
            }
        )
    return out
