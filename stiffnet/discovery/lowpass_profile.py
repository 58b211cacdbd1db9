"""A low-pass the chain fits saw but misplaced, profiled by the law the maps read through it.

A stiffening contact's pulse rises as slowly as a low-pass's, so a record's chain fit (which
models the pulse as a linear contact's) reads the sensor's low-pass at a corner that follows
the contact, not the sensor: behind one 250 Hz second-order low-pass, a power-law contact
(exponent 1.6) had its chain fitted at 216 Hz by the discovery and at 131-209 Hz by the
restoring-force evidence. Neither inverse makes the force more of a function of the state, so
the records are read as recorded (:mod:`.chain_choice`), and through the low-pass left in them
the learned law is bent: exponent 1.70, ``d_r`` 0.53 mm for 0.40, explaining 92.5 % of the
force. Undone at the sensor's own corner the same maps read exponent 1.63, ``d_r`` 0.42 mm at
99.94 %; at 200 and 300 Hz 99.5 and 99.84 %.

So the corner is profiled by the law itself (:func:`profiled_lowpass`): where no reading kept
a chain and a rejected fit showed a low-pass, a few recordings spread over the campaign are
read through a low-pass of that order at corners on a log grid, the law is discovered on each
reading (no bootstrap), and the corner whose law leaves the least of the force unexplained is
kept where it leaves at most :data:`MAX_UNEXPLAINED_RATIO` of what the law leaves as recorded
(a low-pass the sensor lacks, undone, adds ringing the law cannot follow). numpy/scipy only.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from stiffnet.errors import StiffnetError

#: Recordings the corner is profiled on (spread over the campaign); all are read at its best.
PROFILE_RECORDINGS = 8
#: Lowest corner searched, as a fraction of the lowest corner a rejected fit read (a fit reads
#: a stiffening contact's low-pass low: 216 Hz for 250 on the power law above).
LOWEST_FRACTION = 0.5
#: Highest corner searched, as a fraction of the lowest sampling rate (a corner above it
#: barely touches the band: :class:`~stiffnet.effects.sensor_dynamics.SensorDynamics`).
HIGHEST_FRACTION = 0.45
#: Ratio of neighbouring corners on the grid (then one parabolic step in log corner).
GRID_RATIO = 1.2
#: The profiled reading is kept where its law leaves at most this share of the force the law
#: read as recorded leaves unexplained (a clear gain; 0.008 on the power law above).
MAX_UNEXPLAINED_RATIO = 0.5

Reading = Any  # (ContactSamples | None, RestoringForceResult) or the exception it raised
Read = Callable[[int, Any], Any]


def seen_lowpass(results: Sequence[Any]) -> dict[str, float] | None:
    """The low-pass the rejected chain fits read: the lowest corner and the most common order
    (None where no reading kept a chain and none rejected one with a low-pass, or where a
    reading kept its chain: the campaign's chain is then decided by the shared chain's rule).

    Parameters
    ----------
    results : sequence
        The readings' restoring-force results (:class:`RestoringForceResult`).
    """
    from stiffnet.discovery.samples import chain_outcome

    outcomes = [chain_outcome(r) for r in results]
    if "kept" in outcomes:
        return None
    fits = [r.sensor.to_dict() for r, o in zip(results, outcomes, strict=True) if o == "rejected"]
    low = [c for c in fits if c.get("lowpass_hz")]
    if not low:
        return None
    orders = [int(round(float(c.get("lowpass_order") or 2))) for c in low]
    return {
        "lowpass_hz": float(min(c["lowpass_hz"] for c in low)),
        "lowpass_order": float(max(set(orders), key=orders.count)),
    }


def lowpass_sheet(corner_hz: float, order: float) -> dict[str, float]:
    """A data sheet (:data:`~stiffnet.restoring_force.chain.SENSOR_KEYS`) with only a
    Butterworth low-pass: no resonance, no high-pass."""
    return {"resonance_hz": 0.0, "resonance_damping": 0.0, "lowpass_hz": float(corner_hz),
            "lowpass_order": float(order), "highpass_hz": 0.0}  # fmt: skip


def law_unexplained(samples: Sequence[Any], seed: int = 0) -> float:
    """Share of the contact force the law discovered on ``samples`` leaves unexplained
    (``1 -`` its explained fraction; no bootstrap); ``inf`` where no law is learned."""
    from stiffnet.discovery.select import discover_contact_law

    kept = [s for s in samples if s is not None]
    try:
        law = discover_contact_law(kept, n_boot=0, seed=seed)
    except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return np.inf
    return max(1.0 - float(law.explained_fraction), 0.0)


def profiled_lowpass(
    read: Read,
    readings: dict[int, Reading],
    fs_hz: Sequence[float],
    seed: int = 0,
) -> tuple[dict[int, Reading], dict[str, Any] | None]:
    """Every recording read through the low-pass corner the law profiles, where it reads
    clearly better (module notes); else ``readings`` and None.

    Parameters
    ----------
    read : callable
        ``read(i, sheet)``: recording ``i``'s reading through a data sheet
        (:func:`~stiffnet.discovery.samples.record_contact_samples`).
    readings : dict
        Each recording's reading so far (:func:`~stiffnet.discovery.samples.campaign_readings`).
    fs_hz : sequence of float
        Each recording's sampling rate.
    seed : int
        Seed of the discovery's folds.

    Returns
    -------
    tuple
        The readings kept, and where the profiled low-pass was kept its account:
        ``lowpass_hz``, ``lowpass_order``, ``seen_hz`` (the fits' corner),
        ``unexplained_recorded`` and ``unexplained`` (the law's, on the profiled recordings),
        ``profile`` (corner, unexplained) pairs.
    """
    ok = {i: v for i, v in readings.items() if not isinstance(v, Exception)}
    seen = seen_lowpass([v[1] for v in ok.values()])
    if seen is None:
        return readings, None
    answered = sorted(i for i, v in ok.items() if v[0] is not None)
    if len(answered) < 2:
        return readings, None
    picks = _spread(answered, PROFILE_RECORDINGS)
    order = seen["lowpass_order"]
    recorded = law_unexplained([ok[i][0] for i in picks], seed)
    cache: dict[float, float] = {}

    def unexplained(corner: float) -> float:
        key = float(f"{corner:.4g}")
        if key not in cache:
            got = [_samples(_try(read, i, lowpass_sheet(key, order))) for i in picks]
            enough = sum(g is not None for g in got) >= 2
            cache[key] = law_unexplained(got, seed) if enough else np.inf
        return cache[key]

    low = LOWEST_FRACTION * seen["lowpass_hz"]
    high = HIGHEST_FRACTION * min(float(fs_hz[i]) for i in picks)
    if not high > low:
        return readings, None
    grid = np.geomspace(low, high, max(2, int(np.ceil(np.log(high / low) / np.log(GRID_RATIO)))))
    values = np.array([unexplained(c) for c in grid])
    best = float(grid[int(np.argmin(values))])
    k = int(np.argmin(values))
    if 0 < k < grid.size - 1 and np.all(np.isfinite(values[k - 1 : k + 2])):
        step = _parabola_vertex(np.log(grid[k - 1 : k + 2]), np.log(values[k - 1 : k + 2]))
        if step is not None and unexplained(float(np.exp(step))) < unexplained(best):
            best = float(f"{np.exp(step):.4g}")
    u_best = unexplained(best)
    if not (np.isfinite(u_best) and u_best <= MAX_UNEXPLAINED_RATIO * recorded):
        return readings, None
    sheet = lowpass_sheet(float(f"{best:.4g}"), order)
    out = {i: _try(read, i, sheet) for i in readings}
    info = {
        "lowpass_hz": sheet["lowpass_hz"],
        "lowpass_order": order,
        "seen_hz": seen["lowpass_hz"],
        "unexplained_recorded": recorded,
        "unexplained": u_best,
        "recordings": len(picks),
        "profile": [[c, u] for c, u in sorted(cache.items())],
    }
    return out, info


def _parabola_vertex(x: np.ndarray, y: np.ndarray) -> float | None:
    """The vertex of the parabola through three points (None where it opens downwards)."""
    a, b, _ = np.polyfit(x, y, 2)
    if not a > 0:
        return None
    return float(np.clip(-b / (2 * a), x[0], x[-1]))


def _try(read: Read, i: int, sheet: dict[str, float]) -> Reading:
    try:
        return read(i, sheet)
    except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return exc


def _samples(got: Reading) -> Any:
    return None if isinstance(got, Exception) else got[0]


def _spread(indices: list[int], k: int) -> list[int]:
    """``k`` of ``indices`` evenly spread (first and last included)."""
    return sorted({indices[round(j * (len(indices) - 1) / max(k - 1, 1))] for j in range(k)})
