"""The campaign's operating envelope as the training world of the loop's models.

A model retrained by the loop (:mod:`stiffnet.measurement.loop`) is judged on one
campaign, whose operating points the manifest gives: gap, forcing amplitude and
frequency ratio, damping, sampling rate and noise. Drawn over the starting config's
whole sweep (the paper's box, ``configs/sim/ideal.yaml``), most of a small loop
dataset lies where the campaign never goes, and where it does go the sweep may not
reach (the example campaign's ``fs/f_n`` of 158-211 against a test sweep of 60-120).
:func:`campaign_envelope` narrows each swept column to the rows' range, widened by
:data:`MARGIN`; β keeps its sweep (the model must place every class).

Measured on the example campaign with a two-stage law (the learned law of the loop,
300 trajectories, GBM): the model's own test accuracy 0.62 -> 0.82 and β MAPE
0.42 -> 0.14; on the campaign β MAPE 0.26 -> 0.18 while the class accuracy on its
eight recordings went 0.875 -> 0.625 (β 65 and 95 read 52 and 51, 60 and 69 before);
on the independent rig's Hunt-Crossley campaign (150 trajectories) β MAPE 0.18
(docs/measurement_loop.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from stiffnet.campaign.simulate import natural_frequency, row_noise
from stiffnet.config.sim import SimulationConfig

#: Relative widening of each column's range on both sides (of the larger of the range's
#: width and its upper value), so that the rows' own points are not on the edge.
MARGIN = 0.1
#: Columns whose lower bound must stay above zero.
POSITIVE = ("amplitude", "omega", "damping", "fs_ratio")
#: The sweep's columns and how a manifest row gives each (None: the row lacks it).
COLUMNS = {
    "gap": lambda r: r.gap,
    "amplitude": lambda r: r.amplitude,
    "omega": lambda r: r.frequency_ratio,
    "damping": lambda r: r.damping_ratio,
    "noise": row_noise,
    "fs_ratio": lambda r: r.fs_hz / natural_frequency(r),
}


def envelope_range(values: Sequence[float], margin: float = MARGIN) -> tuple[float, float]:
    """``[min - m, max + m]`` with ``m = margin * max(max - min, |max|)``."""
    lo, hi = min(values), max(values)
    m = margin * max(hi - lo, abs(hi))
    return lo - m, hi + m


def campaign_envelope(
    cfg: SimulationConfig, rows: Sequence[Any], margin: float = MARGIN
) -> SimulationConfig:
    """``cfg`` with its sweep narrowed (or moved) to the rows' operating envelope.

    Parameters
    ----------
    cfg : SimulationConfig
        The starting config (its β sweep, classes, effects and windows are kept).
    rows : sequence of ManifestRow
        The campaign's rows; a column no row gives keeps the config's range.
    margin : float
        Relative widening (:func:`envelope_range`).

    Returns
    -------
    SimulationConfig
        A validated copy; a positive column's lower bound stays above zero, and a range
        outside a column's allowed values leaves the config's.
    """
    from pydantic import ValidationError

    sweep_cls = type(cfg.sweep)
    sweep = cfg.sweep.model_dump()
    for col, get in COLUMNS.items():
        values = [float(v) for v in (get(r) for r in rows) if v is not None]
        if not values:
            continue
        lo, hi = envelope_range(values, margin)
        if col in POSITIVE and lo <= 0.0:
            lo = min(values) / 2.0 if min(values) > 0 else sweep[col][0]
        trial = {**sweep, col: (max(lo, 0.0) if col == "noise" else lo, hi)}
        if col == "noise":
            trial["noise_levels"] = None  # the rows' noise range, not discrete levels
        try:
            sweep_cls.model_validate(trial)
        except ValidationError:  # beyond the column's allowed values: the config's range
            continue
        sweep = trial
    return cfg.model_copy(update={"sweep": sweep_cls.model_validate(sweep)})
