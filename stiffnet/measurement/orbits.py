"""Which orbit a recording and its simulations are on (impacts per forcing periods).

An impact oscillator is multistable: at one operating point the same rig can
settle on one impact per forcing period, on two every three, or wander. A
simulation on another orbit than the measurement disagrees whatever the
physics, so the diagnosis profiles the initial state over several starts
(:mod:`stiffnet.measurement.nuisance`) and reports, per recording, the
measured orbit, the orbit of the chosen simulation, how many distinct orbits
the starts reached and whether any reached the measured one. The orbit is
named as :func:`stiffnet.geometry.orbit.impact_pattern` names it (``analyze``
uses the same words), from the impacts the statistics found.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from stiffnet.geometry.orbit import describe_pattern, impact_pattern
from stiffnet.measurement.statistics import SignalStatistics


def orbit_pattern(stats: SignalStatistics | None) -> tuple[int, int] | None:
    """``(n, m)``: ``n`` impacts every ``m`` forcing periods (None: none or no repeat)."""
    if stats is None or not stats.has_impacts or not stats.frequency_ratio:
        return None
    period = stats.fs_hz / (stats.natural_frequency_hz * stats.frequency_ratio)
    return impact_pattern(stats.impacts, period)


def orbit_name(stats: SignalStatistics | None) -> str:
    """The orbit in words ("1 impact per forcing period", "no impacts", ...)."""
    if stats is None:
        return "simulation could not be analysed"
    if not stats.has_impacts:
        return "no impacts"
    pattern = orbit_pattern(stats)
    if pattern is None:
        return f"irregular ({describe_pattern(None)}; {stats.impacts_per_period:.2f} per period)"
    return describe_pattern(pattern)


def start_orbits(
    measured: Sequence[SignalStatistics],
    per_start: Sequence[Sequence[SignalStatistics | None]],
) -> list[dict[str, Any]]:
    """Per recording: the measured orbit, each start's and how many distinct ones they reached.

    Parameters
    ----------
    measured : sequence of SignalStatistics
        The recordings' statistics.
    per_start : sequence of sequences
        ``per_start[k][i]``: the statistics of recording ``i`` simulated from start ``k``.

    Returns
    -------
    list of dict
        ``measured_orbit``, ``start_orbits`` (one name per start), ``distinct_orbits`` and
        ``starts_on_measured_orbit`` (how many starts reached the measured orbit; None when
        the measured orbit has no repeating pattern, so no match can be claimed).
    """
    out = []
    for i, m in enumerate(measured):
        names = [orbit_name(sims[i]) for sims in per_start]
        target = orbit_pattern(m)
        hits = None
        if target is not None:
            hits = sum(orbit_pattern(sims[i]) == target for sims in per_start)
        out.append(
            {
                "measured_orbit": orbit_name(m),
                "start_orbits": names,
                "distinct_orbits": len(set(names)),
                "starts_on_measured_orbit": hits,
            }
        )
    return out


def window_orbits(table: Any) -> list[tuple[int, int] | None]:
    """Each window's orbit ``(n, m)`` in a simulated dataset table, named as a recording's is
    (:func:`orbit_pattern` on the window's statistics; None: no impacts, no repeat or a
    window too short to name one).

    Parameters
    ----------
    table : pyarrow.Table
        Windows with the dataset's columns ``accel``, ``fs_hz``, ``natural_frequency_hz``
        and ``omega`` (forcing over natural frequency).
    """
    import numpy as np

    from stiffnet.measurement.statistics import batch_signal_statistics

    cols = table.select(["accel", "fs_hz", "natural_frequency_hz", "omega"]).to_pydict()
    stats = batch_signal_statistics(
        [np.asarray(a, dtype=np.float64) for a in cols["accel"]],
        cols["fs_hz"], cols["natural_frequency_hz"], cols["omega"], inclination=False,
    )  # fmt: skip
    return [orbit_pattern(s) for s in stats]
