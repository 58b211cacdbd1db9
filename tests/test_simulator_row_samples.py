"""Rows that stop at their own length: the closed form and the sensor chain.

A campaign's rows sampled at 1 kHz need half the samples of those at 2 kHz
(:func:`stiffnet.campaign.simulate.simulate_rows` passes ``row_samples``). The
closed-form engine stops each row at its own count and the sensor chain, causal,
filters no further; what each row keeps must be what the full-length simulation
gives, bit for bit, whatever the later samples are.
"""

from __future__ import annotations

import numpy as np

from stiffnet.effects.contact_damping import ContactDamping
from stiffnet.effects.sensor_dynamics import SensorDynamics
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.compiled import simulate_closed_form
from stiffnet.simulator.simulator import Simulator

BATCH = OscillatorBatch(
    beta=np.array([10.0, 45.0, 90.0]),
    gap=np.array([1.2, 0.5, 2.0]),
    amplitude=np.array([1.3, 1.0, 1.9]),
    omega=np.array([1.0, 1.05, 0.97]),
    damping=np.array([0.02, 0.02, 0.03]),
)
NEED = np.array([1200, 2000, 700])
N = 2000


def test_closed_form_rows_stop_at_their_own_count_with_the_same_samples() -> None:
    sim = Simulator([ContactDamping(damping_ratio=0.2)])
    params = {e.name: e.batch_params(3, np.random.default_rng(0)) for e in sim.effects}
    model = sim.linear_model(BATCH, params)
    x0, v0 = np.array([0.3, -0.5, 1.0]), np.array([0.0, 0.4, -0.2])
    h = 2 * np.pi / np.array([100.0, 160.0, 211.0])
    full = simulate_closed_form(model, x0, v0, 30.0, h, N)
    cut = simulate_closed_form(model, x0, v0, 30.0, h, N, row_samples=NEED)
    for i, m in enumerate(NEED):
        for key in ("x", "v", "contact_force", "accel", "impacts"):
            a, b = getattr(full, key)[i], getattr(cut, key)[i]
            assert np.array_equal(a[:m], b[:m]), (key, i)
            assert not np.any(b[m:]), (key, i)  # not simulated: left at 0
        assert full.impacts[i, :m].sum() > 0  # the rows impact: the events are exercised


def test_sensor_chain_filters_each_row_to_its_own_count_and_no_further() -> None:
    sensor = SensorDynamics(resonance_hz=237.0, resonance_damping=0.03, highpass_hz=1.0,
                            lowpass_hz=0.0)  # fmt: skip
    sim = Simulator([ContactDamping(damping_ratio=0.2), sensor])
    fs_ratio = np.array([8 * 105.5, 8 * 131.9, 8 * 211.0])
    kw = {"noise": 0.02, "x0": np.array([0.3, -0.5, 1.0]), "v0": np.array([0.0, 0.4, -0.2])}
    full = sim.simulate(BATCH, fs_ratio, N, rng=5, **kw).accel
    cut = sim.simulate(BATCH, fs_ratio, N, rng=5, row_samples=NEED, **kw).accel
    for i, m in enumerate(NEED):
        assert np.array_equal(full[i, :m], cut[i, :m]), i
    # the filter ran: the chain's output differs from its input on every row
    raw = Simulator([ContactDamping(damping_ratio=0.2)]).simulate(
        BATCH, fs_ratio, N, rng=5, row_samples=NEED, **kw
    ).accel  # fmt: skip
    assert all(not np.allclose(raw[i, :m], cut[i, :m]) for i, m in enumerate(NEED))
