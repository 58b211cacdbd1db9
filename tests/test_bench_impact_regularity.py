"""benchmarks/bench_impact_regularity.py: what its per-impact readings tell apart."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from stiffnet.restoring_force.contact_law import ContactLaw

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture
def regularity(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import bench_impact_regularity

    return bench_impact_regularity


def _map(amplitudes, levels, stiffness=50.0, samples=10, flight=12, noise=0.05):
    """A restoring-force map of half-sine impacts through a linear law: each impact's true
    peak penetration (`amplitudes`), the map's level error during it (`levels`) and white
    noise on the force (`noise`, 0.1 % of a unit impact's peak)."""
    disp, force = [], []
    for a, level in zip(amplitudes, levels, strict=True):
        true = a * np.sin(np.pi * (np.arange(samples) + 0.5) / samples)
        disp += [np.full(flight, -1.0), true + level]
        force += [np.zeros(flight), stiffness * true]
    disp, force = np.concatenate(disp), np.concatenate(force)
    force = force + np.random.default_rng(7).normal(0.0, noise, force.size)
    law = ContactLaw(stiffness=stiffness, onset=0.0, damping=0.0, exponent=1.0,
                     reference_penetration=1.0, r2=0.99)  # fmt: skip
    return SimpleNamespace(displacement=disp, velocity=np.zeros_like(disp), force=force, law=law)


def test_a_wandering_level_is_no_change_of_depth(regularity):
    """Identical impacts read at levels that wander by 10 %: the depths spread, but neither
    the impulse nor the peak force follows them (slope near 0); the law fits every one."""
    rng = np.random.default_rng(3)
    r = _map(np.ones(20), rng.uniform(0.0, 0.1, 20))
    s = regularity.spread(regularity.impact_readings(r))
    assert s["depth_p90_p10"] > 1.05
    assert s["impulse_cv"] < 1e-3 and s["peak_cv"] < 1e-3
    assert abs(s["peak_on_depth"]) < 0.05


def test_impacts_of_different_depths_carry_their_impulse(regularity):
    """Impacts whose true depths differ by up to 30 % through a linear law, read at the right
    level: the impulse spreads with them and the peak force follows the depth (slope 1)."""
    r = _map(np.linspace(0.85, 1.15, 20), np.zeros(20))
    s = regularity.spread(regularity.impact_readings(r))
    assert s["impulse_cv"] > 0.05
    assert s["peak_on_depth"] == pytest.approx(1.0, abs=0.02)
    assert s["impulse_cv"] > regularity.VARIED_IMPULSE_CV
