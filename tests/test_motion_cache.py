"""Reuse of the motion between simulations that differ only in their measurement chain
(:mod:`stiffnet.simulator.motion_cache`): bitwise the same signals, and reused."""

from __future__ import annotations

import numpy as np

from stiffnet.effects.registry import effect_class
from stiffnet.simulator import motion_cache
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.simulator import Simulator


def _batch() -> OscillatorBatch:
    n = 3
    return OscillatorBatch(
        np.array([10.0, 40.0, 90.0]), np.array([1.0, 1.5, 0.5]), np.full(n, 1.5),
        np.array([1.0, 1.05, 0.95]), np.full(n, 0.02),
    )  # fmt: skip


def _run(effects, **kw):
    return (
        Simulator(effects)
        .simulate(_batch(), 200.0, 800, noise=0.02, rng=np.random.default_rng(3), **kw)
        .accel
    )


def test_reused_motion_gives_bitwise_the_same_signals_and_is_reused(monkeypatch):
    sensor, damping = effect_class("sensor_dynamics"), effect_class("contact_damping")
    models = [
        [damping(damping_ratio=0.2), sensor(resonance_hz=300.0, highpass_hz=0.0)],
        [damping(damping_ratio=0.2), sensor(resonance_hz=500.0, resonance_damping=0.1)],
        [damping(damping_ratio=0.3), sensor(resonance_hz=300.0, highpass_hz=0.0)],
    ]
    fresh = [_run(m) for m in models]
    calls = []
    real = Simulator._motion
    monkeypatch.setattr(Simulator, "_motion", lambda self, *a: calls.append(1) or real(self, *a))
    with motion_cache.reuse_motion():
        reused = [_run(m) for m in models]
        again = _run(models[0])
    for a, b in zip(fresh, reused, strict=True):
        assert np.array_equal(a, b)
    assert np.array_equal(again, fresh[0])
    assert len(calls) == 2  # the sensor moved alone once: one motion for two chains
    # another initial state is another motion
    with motion_cache.reuse_motion():
        _run(models[0])
        _run(models[0], x0=np.zeros(3), v0=np.zeros(3))
    assert len(calls) == 4
    assert not motion_cache._STORE  # nothing kept outside the block


def test_a_longer_motion_serves_a_shorter_record_as_its_prefix(monkeypatch):
    sensor = effect_class("sensor_dynamics")
    model = [effect_class("contact_damping")(damping_ratio=0.2), sensor(highpass_hz=0.0)]

    def run(n):
        return Simulator(model).simulate(_batch(), 200.0, n, rng=np.random.default_rng(3))

    fresh = run(500)
    calls = []
    real = Simulator._motion
    monkeypatch.setattr(Simulator, "_motion", lambda self, *a: calls.append(1) or real(self, *a))
    with motion_cache.reuse_motion():
        run(800)
        short = run(500)
    assert len(calls) == 1
    assert np.array_equal(short.accel, fresh.accel) and np.array_equal(short.x, fresh.x)
    assert short.accel.shape == (3, 500)
