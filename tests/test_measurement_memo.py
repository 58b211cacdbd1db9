"""A target's per-recording results computed once per inputs (CampaignTarget.known):
reused results equal recomputed ones, any input that changes the result is a new entry,
and a fit gives the same result with the reuse on and off."""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.campaign import ManifestRow
from stiffnet.campaign.simulate import FIT_SETTINGS, simulate_rows
from stiffnet.effects.registry import effect_class
from stiffnet.measurement import target as target_module
from stiffnet.measurement.fitting import fit_effect, fit_joint
from stiffnet.measurement.statistics import signal_statistics
from stiffnet.measurement.target import CampaignTarget

ROW = ManifestRow(
    recording="a.csv", fs_hz=1250, beta=30.0, gap=1.0, amplitude=1.0,
    frequency_ratio=1.0, damping_ratio=0.05,
)  # fmt: skip
ROWS = [ROW, ROW.model_copy(update={"recording": "b.csv", "beta": 60.0})]
N = 3000


@pytest.fixture(scope="module")
def measured():
    damped = [effect_class("contact_damping")(damping_ratio=0.3)]
    sims = simulate_rows(ROWS, damped, [N, N], seed=3, settings=FIT_SETTINGS)
    return [signal_statistics(a, r.fs_hz, 9.48, 1.0) for a, r in zip(sims, ROWS, strict=True)]


def make(measured, inclination=False) -> CampaignTarget:
    return CampaignTarget(list(ROWS), measured, [N, N], [], seed=11, inclination=inclination)


@pytest.fixture
def counted(monkeypatch):
    calls = []
    real = target_module.simulate_rows

    def counting(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(target_module, "simulate_rows", counting)
    return calls


def damping(z: float):
    return effect_class("contact_damping")(damping_ratio=z)


def test_a_repeated_evaluation_is_served_and_equals_a_fresh_one(measured, counted):
    t = make(measured)
    first = t.per_recording([damping(0.2)], FIT_SETTINGS)
    first[:] = -1.0  # the caller's copy: the kept one is untouched
    again = t.per_recording([damping(0.2)], FIT_SETTINGS)
    assert len(counted) == 1
    fresh = make(measured).per_recording([damping(0.2)], FIT_SETTINGS)
    np.testing.assert_array_equal(again, fresh)
    assert np.all(again > 0)


@pytest.mark.parametrize(
    "change",
    ["effect value", "effect class", "row value", "starts", "settings", "oversample", "seed"],
)
def test_every_input_that_moves_the_result_is_a_new_entry(measured, counted, change):
    t = make(measured)
    base = dict(effects=[damping(0.2)], settings=FIT_SETTINGS, rows=None, starts=None)
    t.per_recording(**base)
    other = dict(base)
    if change == "effect value":
        other["effects"] = [damping(0.2 + 1e-9)]
    elif change == "effect class":
        other["effects"] = [effect_class("forcing_harmonics")()]
    elif change == "row value":
        other["rows"] = [ROWS[0], ROWS[1].model_copy(update={"gap": 1.0 + 1e-9})]
    elif change == "starts":
        other["starts"] = [0, 1]
    elif change == "settings":
        other["settings"] = FIT_SETTINGS.model_copy(update={"periods": 39.0})
    elif change == "oversample":
        other["effects"] = [*base["effects"], effect_class("sensor_dynamics")()]
        t.per_recording(**other)
        counted.clear()
        t.per_recording(**other, oversample=False)
    elif change == "seed":
        t.seed = 12
    if change != "oversample":
        got = t.per_recording(**other)
        assert len(counted) == 2  # simulated again
        fresh = make(measured)
        fresh.seed = t.seed
        np.testing.assert_array_equal(got, fresh.per_recording(**other))
    else:
        assert len(counted) == 1


def test_fits_are_the_same_with_the_reuse_on_and_off(measured, monkeypatch, counted):
    """A single fit and a joint refit (which asks again for the points it starts from)."""

    def run() -> tuple[dict, dict]:
        t = make(measured, inclination=True)
        single = fit_effect(t, "contact_damping", [], budget=8)
        joint = fit_joint(t, ["contact_damping"], [single["params"]], FIT_SETTINGS, budget=4)
        return single, joint

    on = run()
    simulated_on = len(counted)
    monkeypatch.setattr(target_module, "MEMO_ENTRIES", 0)
    off = run()
    assert simulated_on < len(counted) - simulated_on  # the reuse saved simulations
    for a, b in zip(on, off, strict=True):
        for key in a:
            if key != "seconds":
                assert (
                    np.array_equal(a[key], b[key]) if key == "per_recording" else (a[key] == b[key])
                ), key
