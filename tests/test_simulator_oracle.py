"""The closed-form engine (compiled, numba) against its numpy test oracle.

:func:`closed_form_reference` shares the model and the step rule but not the code:
it marches the whole batch with numpy calls and evaluates the samples afterwards.
Both are exact up to round-off, but round-off is all it takes for a chaotic orbit
to part ways after a long transient, so the batches here use short transients
(tens of time units): the engines must then agree to round-off amplified a little.

Impact counts: the oracle logs a spurious zero-length contact (entry,
release, re-entry within ~1e-13) when its located root lands a round-off inside
the old region, and counts a contact already under way at its first-sample
snapshot as an entry; the engine does neither. Counts may differ only
that way: the oracle's count one higher at a sample, never the other way round.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_closed_form import closed_form_reference

from stiffnet.effects.contact_damping import ContactDamping
from stiffnet.effects.forcing_harmonics import ForcingHarmonics
from stiffnet.effects.gap_drift import GapDrift
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.compiled import simulate_closed_form
from stiffnet.simulator.result import EngineResult
from stiffnet.simulator.simulator import Simulator

DOMAIN = {
    "beta": (5.0, 100.0),
    "gap": (0.0, 3.0),
    "amplitude": (0.2, 2.0),
    "omega": (0.8, 1.2),
    "damping": (0.01, 0.05),
}


def _random_case(n: int, effects: bool, seed: int):
    rng = np.random.default_rng(seed)
    batch = OscillatorBatch(**{k: rng.uniform(lo, hi, n) for k, (lo, hi) in DOMAIN.items()})
    x0 = rng.uniform(-1, 1, n) * batch.amplitude
    v0 = rng.uniform(-1, 1, n) * batch.amplitude * batch.omega
    eff = (
        [
            ContactDamping(damping_ratio=[0.0, 0.3]),
            ForcingHarmonics(second=0.05, third=0.02, phase_second=0.5, phase_third=-1.0),
            GapDrift(amplitude=0.2, period=20.0, phase=0.3),
        ]
        if effects
        else []
    )
    sim = Simulator(eff)
    params = {e.name: e.batch_params(n, rng) for e in sim.effects}
    model = sim.linear_model(batch, params)
    h = 2 * np.pi / rng.uniform(50, 500, n)
    t_first = rng.uniform(20.0, 40.0, n)
    return model, x0, v0, t_first, h


@pytest.mark.parametrize("effects", [False, True])
@pytest.mark.parametrize("parallel", [False, True])
def test_engine_matches_oracle(effects: bool, parallel: bool) -> None:
    model, x0, v0, t_first, h = _random_case(120, effects, seed=3)
    n = 300
    a = closed_form_reference(model, x0, v0, t_first, h, n)
    b = simulate_closed_form(model, x0, v0, t_first, h, n, parallel=parallel)
    assert isinstance(a, EngineResult) and isinstance(b, EngineResult)
    for key in ("x", "v", "accel", "contact_force"):
        assert getattr(b, key).shape == (120, n) == getattr(a, key).shape
        assert getattr(b, key).dtype == np.float64 == getattr(a, key).dtype
    assert b.impacts.dtype == np.int8
    np.testing.assert_array_equal(b.t0, a.t0)
    peak = np.abs(a.accel).max(axis=1)
    err = np.abs(a.accel - b.accel).max(axis=1) / peak
    assert err.max() <= 1e-8, f"rows {np.flatnonzero(err > 1e-8)}: {err.max():.1e}"
    extra = a.impacts.astype(int) - b.impacts
    assert extra.min() >= 0  # the engine never counts more
    assert extra.sum() <= 0.05 * a.impacts.sum() + 1
    assert b.impacts.sum() > 20  # the batch does impact


@pytest.mark.parametrize("depth", [1e-6, -1e-6])
def test_grazing_contact_identical(depth: float) -> None:
    beta, xi, v0 = 50.0, 0.02, 1.0
    h = np.array([2 * np.pi / 100.0])
    wd = math.sqrt(1 - xi * xi)
    t_peak = math.atan2(wd, xi) / wd
    x_peak = math.exp(-xi * t_peak) * v0 / wd * math.sin(wd * t_peak)
    batch = OscillatorBatch.single(beta, x_peak - depth, 0.0, 1.0, xi)
    model = Simulator().linear_model(batch, {})
    args = (model, np.zeros(1), np.array([v0]), h, h, 40)
    a = closed_form_reference(*args)
    b = simulate_closed_form(*args)
    np.testing.assert_array_equal(b.impacts, a.impacts)
    assert b.impacts.sum() == (1 if depth > 0 else 0)
    np.testing.assert_allclose(b.x, a.x, rtol=0, atol=1e-13)
    np.testing.assert_allclose(b.v, a.v, rtol=0, atol=1e-13)
    assert not np.any(b.contact_force > 0)
