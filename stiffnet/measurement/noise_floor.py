"""The campaign's own noise floor and the verdict on what is left unexplained.

A perfect simulator does not score zero: the statistics of a finite, noisy
record scatter. How much they scatter is measured on the campaign itself,
by **split-half repeatability**: each recording's statistics on its first
and second halves are compared like a simulation with a measurement
(:func:`stiffnet.measurement.discrepancy.recording_discrepancy`), which gives
``D_half``. A statistic's variance falls as one over the record length, so
two independent halves of ``L`` natural periods differ by ``4 c / L`` and a
simulation of ``P`` periods against the whole recording by ``c (1/P + 1/L)``:
the floor of a recording is ``D_half L (1/P + 1/L) / 4`` and the campaign's
the median over recordings (a recording whose halves differ because its orbit
changes, or a statistic that quantises on a short half, would otherwise set
it). Halves are short, so edge effects (a spike more or less, fewer Welch
segments) make this a conservative, upper estimate.

The verdict (:func:`verdict`) compares discrepancies with that floor: a model
is *at the floor* when its discrepancy is within
:data:`~stiffnet.measurement.significance.AT_FLOOR_FACTOR` times it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from stiffnet.campaign import ManifestRow
from stiffnet.campaign.simulate import natural_frequency
from stiffnet.errors import SignalError
from stiffnet.measurement.discrepancy import (
    WHERE,
    normalised_differences,
    recording_discrepancy,
    where_sums,
)
from stiffnet.measurement.significance import AT_FLOOR_FACTOR
from stiffnet.measurement.statistics import SignalStatistics, signal_statistics


def split_half(
    accel: np.ndarray, row: ManifestRow, inclination: bool = True
) -> tuple[SignalStatistics, SignalStatistics] | None:
    """Statistics of the two halves of a recording (None when a half is too short)."""
    h = accel.size // 2
    try:
        return tuple(  # type: ignore[return-value]
            signal_statistics(
                part, row.fs_hz, natural_frequency(row), row.frequency_ratio, inclination
            )
            for part in (accel[:h], accel[h : 2 * h])
        )
    except SignalError:
        return None


def noise_floor(
    signals: Sequence[np.ndarray],
    rows: Sequence[ManifestRow],
    simulated_periods: float | None,
    inclination: bool = True,
) -> dict[str, Any]:
    """The campaign's noise floor by split-half repeatability (see the module notes).

    Parameters
    ----------
    signals : sequence of numpy.ndarray
        The recordings.
    rows : sequence of ManifestRow
        Their rows (sampling rate, ``f_n``, forcing frequency).
    simulated_periods : float or None
        Natural periods simulated per row in the comparison (None: the recording's length).
    inclination : bool
        Whether the discrepancy includes the inclination statistics.

    Returns
    -------
    dict
        ``floor`` (campaign), ``per_recording``, ``split_half`` (``D_half`` per
        recording; NaN when too short) and ``where`` (the floor per :data:`WHERE`
        group, in the units of :func:`~stiffnet.measurement.discrepancy.where_sums`).
    """
    per, halves, where = [], [], {g: [] for g in WHERE}
    for accel, row in zip(signals, rows, strict=True):
        pair = split_half(np.asarray(accel, float), row, inclination)
        length = accel.size * natural_frequency(row) / row.fs_hz  # natural periods
        p = length if simulated_periods is None else min(length, simulated_periods)
        scale = length * (1.0 / p + 1.0 / length) / 4.0
        if pair is None:
            halves.append(float("nan"))
            per.append(float("nan"))
            continue
        d = recording_discrepancy(normalised_differences(*pair))
        halves.append(d)
        per.append(d * scale)
        for g, v in where_sums(*pair).items():
            where[g].append(v * scale)
    per_arr = np.asarray(per, float)
    return {
        "floor": float(np.nanmedian(per_arr)) if np.isfinite(per_arr).any() else 0.0,
        "per_recording": [None if not np.isfinite(v) else float(v) for v in per],
        "split_half": [None if not np.isfinite(v) else float(v) for v in halves],
        "where": {g: float(np.median(v)) if v else 0.0 for g, v in where.items()},
    }


def rescale_floor(
    info: dict[str, Any],
    signals: Sequence[np.ndarray],
    rows: Sequence[ManifestRow],
    simulated_periods: float | None,
) -> float:
    """The floor of :func:`noise_floor`'s result for another simulated length."""
    out = []
    for d, accel, row in zip(info["split_half"], signals, rows, strict=True):
        if d is None:
            continue
        length = accel.size * natural_frequency(row) / row.fs_hz
        p = length if simulated_periods is None else min(length, simulated_periods)
        out.append(d * length * (1.0 / p + 1.0 / length) / 4.0)
    return float(np.median(out)) if out else 0.0


def at_floor(discrepancy: float, floor: float) -> bool:
    """True when a discrepancy is within the noise floor's band."""
    return discrepancy <= AT_FLOOR_FACTOR * floor


def verdict(
    baseline: float,
    residual: float,
    floor: float,
    selected: Sequence[str],
    residual_where: dict[str, float],
    floor_where: dict[str, float],
) -> dict[str, Any]:
    """What the selected effects explain, and where the rest lives.

    ``nothing_missing`` only when the base model is at the noise floor;
    ``explained`` when effects were selected and the model with them is at the
    floor; otherwise ``partially_explained`` (also when nothing in the library
    helps but the base model is above the floor: the missing physics is not in
    the library).

    Returns
    -------
    dict
        ``verdict``, ``residual_discrepancy``, ``explained_fraction`` (of the
        baseline's excess over the floor), ``noise_floor``, ``unexplained_where``
        (share of the residual's excess over the floor per :data:`WHERE` group,
        None when nothing is left) and ``summary`` (one sentence).
    """
    excess = baseline - floor
    explained = float(np.clip((baseline - residual) / excess, 0.0, 1.0)) if excess > 0 else 1.0
    left = {g: max(0.0, residual_where.get(g, 0.0) - floor_where.get(g, 0.0)) for g in WHERE}
    total = sum(left.values())
    shares = {g: v / total for g, v in left.items()} if total > 0 else None
    if at_floor(baseline, floor):
        v = "nothing_missing"
        text = f"the base model is at the campaign's noise floor ({baseline:.3g} vs {floor:.3g})"
        shares = None
    elif selected and at_floor(residual, floor):
        v = "explained"
        text = (
            f"{', '.join(selected)} bring the discrepancy from {baseline:.3g} to the noise "
            f"floor ({residual:.3g} vs {floor:.3g})"
        )
        shares = None
    else:
        v = "partially_explained"
        where = max(shares, key=shares.get) if shares else "unknown"
        what = ", ".join(selected) if selected else "no effect of the library"
        text = (
            f"{what} explain{'s' if len(selected) <= 1 else ''} {explained:.0%} of the "
            f"discrepancy above the noise floor; {residual:.3g} is left (floor {floor:.3g}), "
            f"mostly in {where.replace('_', ' ')}: physics the candidates lack"
        )
    return {
        "verdict": v,
        "residual_discrepancy": float(residual),
        "explained_fraction": explained,
        "noise_floor": float(floor),
        "unexplained_where": shares,
        "summary": text,
    }
