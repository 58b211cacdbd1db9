"""Shaker harmonics at random levels and phases fitted on campaigns from the independent rig.

The global stage reads the harmonics off the free flights in closed form
(:mod:`stiffnet.measurement.forcing_lines`); the local search then stays within the
reading's confidence region, with each recording's initial state profiled again at the
reading (the harmonics move the orbit: a start profiled without them can settle on
another orbit than the recording, :func:`stiffnet.measurement.fitting.starts_at`).
Before, a Sobol design and a free local search on the same rig's 8 recordings
(0.25 / 0.074, 0.12 / 2.83) ended at 0.096 / 2.52, 0.142 / 1.54 (diagnose: partially
explained); now at 0.248 / 0.085, 0.120 / 2.817 (explained).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from independent_rig import write_campaign
from test_independent_rig import POINTS, _runs

from stiffnet.campaign import load_campaign
from stiffnet.campaign.simulate import FIT_SETTINGS
from stiffnet.effects.registry import effect_class
from stiffnet.measurement.fitting import fit_effect, starts_at
from stiffnet.measurement.forcing_lines import campaign_forcing_lines
from stiffnet.measurement.nuisance import N_STARTS, profile_nuisances, resolve_rows
from stiffnet.measurement.target import CampaignTarget, measured_statistics

pytestmark = pytest.mark.slow


def _draw(seed: int) -> dict[str, float]:
    """Levels and phases drawn at random (the shaker's: 0.15-0.3 and 0.06-0.15)."""
    rng = np.random.default_rng(seed)
    second, third = rng.uniform(0.15, 0.3), rng.uniform(0.06, 0.15)
    phases = rng.uniform(-math.pi, math.pi, 2)
    return {"second": second, "phase_second": phases[0], "third": third,
            "phase_third": phases[1]}  # fmt: skip


def _target(tmp_path, truth: dict[str, float]) -> CampaignTarget:
    """The rig's 8 operating points, 4 s each, 2 % noise, with the harmonics; the target
    as the diagnosis builds it (rows resolved, nuisances and starts profiled, the
    harmonics read)."""
    harmonics = ((2, truth["second"], truth["phase_second"]),
                 (3, truth["third"], truth["phase_third"]))  # fmt: skip
    folder = write_campaign(tmp_path / "harm", _runs(POINTS, 4.0, harmonics=harmonics))
    campaign = load_campaign(folder)
    rows, info = resolve_rows(campaign)
    measured, lengths, signals = measured_statistics(campaign, rows, inclination=False)
    target = CampaignTarget(rows, measured, lengths, inclination=False)
    profile_nuisances(target, [], FIT_SETTINGS, info)
    target.forcing = campaign_forcing_lines(signals, rows)
    return target


def _errors(params: dict[str, float], truth: dict[str, float]) -> tuple[float, float]:
    level = max(abs(params[k] / truth[k] - 1) for k in ("second", "third"))
    phase = max(abs(math.remainder(params[k] - truth[k], 2 * math.pi))
                for k in ("phase_second", "phase_third"))  # fmt: skip
    return level, phase


@pytest.mark.parametrize("seed", [1, 2])
def test_random_phase_harmonics_fitted_within_10_percent_and_02_rad(tmp_path, seed):
    """Measured (load 8-12), largest level / phase error of the fit and of the reading alone:
    draw 1 (0.227 / -2.236, 0.146 / 2.819) 5.3 % / 0.037 rad, reading 0.9 % / 0.017;
    draw 2 (0.189 / 1.974, 0.087 / -2.564) 3.6 % / 0.058 rad, reading 0.6 % / 0.017.
    Main's search on such a campaign ended 62 % / 1.3 rad off (see the module notes)."""
    truth = _draw(seed)
    target = _target(tmp_path, truth)
    read_level, read_phase = _errors(target.forcing, truth)
    assert read_level < 0.05 and read_phase < 0.1, target.forcing  # the global stage alone
    fit = fit_effect(target, "forcing_harmonics")
    level, phase = _errors(fit["params"], truth)
    assert fit["improves"] and level < 0.10 and phase < 0.2, (fit["params"], truth)


def test_a_recording_that_jumps_orbit_at_the_reading_gets_its_start_profiled_there(tmp_path):
    """At the harmonics of draw 0 a recording can settle on another orbit than the rig's
    from a start profiled without them (it did on the masked free-flight harmonics; on the
    bridged ones the profile picks the right orbit already): that recording held at its
    worst start at the truth, profiling the starts again at the reading moves it back."""
    truth = {"second": 0.25, "phase_second": 0.074, "third": 0.12, "phase_third": 2.83}
    target = _target(tmp_path, truth)
    model = [effect_class("forcing_harmonics")(**truth)]
    n = len(target.rows)
    pers = np.vstack(
        [
            target.per_recording(model, FIT_SETTINGS, starts=[k] * n, inclination=False)
            for k in range(N_STARTS)
        ]
    )
    worst, rec = np.unravel_index(int(np.argmax(pers)), pers.shape)
    starts = list(target.starts)
    starts[rec] = int(worst)
    target = replace(target, starts=starts)
    held = target.per_recording(model, FIT_SETTINGS, inclination=False)
    moved = starts_at(target, model, FIT_SETTINGS)
    again = moved.per_recording(model, FIT_SETTINGS, inclination=False)
    assert np.all(again <= held) and held.max() > 1.0 and again.max() < held.max() / 4
    assert target.starts != moved.starts and target.starts is not moved.starts
