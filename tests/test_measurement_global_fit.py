"""The global stage of a fit: grids over the parameters an effect declares multimodal
(phases, frequencies) before the local search, so a fit reaches the truth's basin."""

from __future__ import annotations

import math

import numpy as np
import pytest
from user_effects import PhasedHarmonics

from stiffnet.campaign.simulate import FIT_SETTINGS
from stiffnet.effects.fit_space import AMPLITUDE_LEVELS, AXIS_GRID, PHASE_GRID, global_blocks
from stiffnet.effects.registry import CANONICAL, effect_class
from stiffnet.measurement import fitting

#: The shaker's harmonics with their phases declared multimodal: a user effect, loaded as
#: a plugin like a user's (``tests/user_effects.py``).
PHASED = "user_effects:PhasedHarmonics"


class _Row:
    fs_hz = 1000.0


class PhaseTarget:
    """A campaign stand-in whose discrepancy is an analytic function of the harmonics:
    quadratic in the levels and, in each phase, ``1 - cos d + 0.8 (1 - cos 3d)`` (local
    minima near d = +-2.1 rad, which trap a local search started on the wrong side)."""

    rows = [_Row()] * 3
    base_effects: list = []
    weights = None
    inclination = False
    starts = None

    def __init__(self, truth: dict[str, float]) -> None:
        self.truth = truth

    def observed(self) -> dict[str, float]:
        return {}

    def per_recording(self, effects, settings, rows=None, starts=None, inclination=None):
        p = {} if not effects else effects[-1].params.model_dump()
        t = self.truth
        d = 0.0
        for amp, ph in (("second", "phase_second"), ("third", "phase_third")):
            a = p.get(amp, 0.0)
            delta = p.get(ph, 0.0) - t[ph]
            d += 40 * (a - t[amp]) ** 2
            d += a * t[amp] * 20 * ((1 - math.cos(delta)) + 0.8 * (1 - math.cos(3 * delta)))
        return np.full(3, 0.01 + d)


def test_every_declared_multimodal_parameter_has_a_grid():
    """...or is read off the measurement (``global_seeds``: the harmonics' phases)."""
    for name in CANONICAL:
        space = effect_class(name).campaign_fit_space(1000.0)
        blocks = global_blocks(space)
        assert len(blocks) == (0 if space.global_seeds else len(space.multimodal))
        for idx, grid in blocks:
            assert grid.shape[1] == len(idx) and np.all((grid >= 0) & (grid <= 1))
    fh = global_blocks(PhasedHarmonics.fit_space)
    assert [len(g) for _, g in fh] == [PHASE_GRID * len(AMPLITUDE_LEVELS)] * 2
    sensor = global_blocks(effect_class("sensor_dynamics").fit_space)
    assert [len(g) for _, g in sensor] == [AXIS_GRID]


TRUTHS = [
    {"second": 0.2, "phase_second": 2.6, "third": 0.12, "phase_third": -2.4},
    {"second": 0.25, "phase_second": -2.5, "third": 0.1, "phase_third": 2.0},
    {"second": 0.15, "phase_second": 0.9, "third": 0.08, "phase_third": -2.9},
]


def _error(params, truth):
    level = max(abs(params[k] / truth[k] - 1) for k in ("second", "third"))
    phase = max(
        abs(math.remainder(params[k] - truth[k], 2 * math.pi))
        for k in ("phase_second", "phase_third")
    )
    return level, phase


@pytest.mark.parametrize("truth", TRUTHS)
def test_random_phase_harmonics_are_fitted_within_10_percent_and_02_rad(truth):
    fit = fitting.fit_effect(PhaseTarget(truth), PHASED, settings=FIT_SETTINGS)
    level, phase = _error(fit["params"], truth)
    assert level < 0.10 and phase < 0.2, fit["params"]


def test_without_the_global_stage_a_local_search_stops_short(monkeypatch):
    monkeypatch.setattr(fitting, "global_blocks", lambda space: [])
    misses = 0
    for truth in TRUTHS:
        fit = fitting.fit_effect(PhaseTarget(truth), PHASED, settings=FIT_SETTINGS)
        level, phase = _error(fit["params"], truth)
        misses += not (level < 0.10 and phase < 0.2)
    assert misses >= 1
