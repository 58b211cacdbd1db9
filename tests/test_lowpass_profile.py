"""The low-pass the chain fits misplace, profiled by the law the maps read through it.

Fast tests: readings written from a known power law whose force lags the penetration by
an amount that grows with how far the corner undone is from the sensor's (a low-pass left
in the record delays the force; its inverse at the right corner removes the delay). The
profile's rule is tested with the law's unexplained force stood in for by a quartic's in the
penetration alone (a discovery per corner costs 1-2 s); the law itself reads the lag in
one test. The independent rig's campaign behind
a real 250 Hz low-pass is the slow test in ``test_discovery_independent_rig.py``.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from stiffnet.discovery import ContactSamples, lowpass_profile
from stiffnet.discovery.lowpass_profile import (
    MAX_UNEXPLAINED_RATIO,
    law_unexplained,
    profiled_lowpass,
    seen_lowpass,
)
from stiffnet.effects.learned_contact import learned_contact_force

SENSOR_HZ = 250.0
LAW = {"exponent": 1.6, "reference_penetration": 0.4, "knee": 0.0, "knee_ratio": 1.0,
       "preload": 0.0, "hunt_crossley": 0.0, "damping_ratio": 0.0}  # fmt: skip
BETAS = (8.0, 20.0, 45.0, 90.0)


def lagged_samples(r: int, lag: float, seed: int = 0, n_impacts: int = 8) -> ContactSamples:
    """Recording ``r``'s impacts from :data:`LAW`, the force ``lag`` (a fraction of the contact's
    half period) behind the penetration, with 0.2 % noise."""
    rng = np.random.default_rng([seed, r])
    beta = BETAS[r % len(BETAS)]
    om = np.sqrt(1.0 + beta)
    t = np.linspace(-0.4, 1.4, 28) * np.pi / om
    xs, vs, fs, imp = [], [], [], []
    for j in range(n_impacts):
        amp = 0.6 / np.sqrt(beta / 8.0) * rng.uniform(0.7, 1.3)
        delta = amp * np.sin(om * t)
        late = amp * np.sin(om * (t - lag * np.pi / om))
        f = learned_contact_force(late, np.zeros_like(late), beta, LAW)
        fs.append(f + 0.002 * f.max() * rng.standard_normal(f.size))
        xs.append(delta + 1.5)
        vs.append(amp * om * np.cos(om * t))
        imp.append(np.full(t.size, j + 1))
    cat = np.concatenate
    return ContactSamples(f"r{r}", cat(xs), cat(vs), cat(fs), cat(imp), 1.5, beta)


@pytest.fixture
def cubic_stand_in(monkeypatch):
    """The law's unexplained force stood in for by a static quartic's (module notes)."""

    def unexplained(samples, seed=0):
        lost = []
        for s in samples:
            inside = s.displacement > s.onset
            x, f = s.displacement[inside] - s.onset, s.force[inside]
            fit = np.polyval(np.polyfit(x, f, 4), x)
            lost.append(np.sum((f - fit) ** 2) / np.sum((f - f.mean()) ** 2))
        return float(np.median(lost))

    monkeypatch.setattr(lowpass_profile, "law_unexplained", unexplained)


def _result(outcome: str, chain: dict | None = None) -> SimpleNamespace:
    """A restoring-force result whose chain fit did ``outcome`` (:func:`chain_outcome`)."""
    if outcome == "none":
        return SimpleNamespace(sensor=None)
    sensor = SimpleNamespace(source="fitted", applied=outcome == "kept", has_dynamics=True,
                             to_dict=lambda: dict(chain or {}))  # fmt: skip
    return SimpleNamespace(sensor=sensor)


def campaign(fits: dict[int, tuple[str, dict | None]], n: int = 4, recorded_lag: float = 0.12):
    """``(readings, read, sheets)`` of ``n`` recordings read as recorded (the force
    ``recorded_lag`` late; ``fits``: the recordings whose chain fit did something), and the
    reading through a data sheet's low-pass, its lag growing with ``|log(corner / 250 Hz)|``."""
    sheets: list[dict] = []

    def read(i, sheet):
        assert isinstance(sheet, dict)
        sheets.append(sheet)
        lag = 0.15 * abs(np.log(sheet["lowpass_hz"] / SENSOR_HZ))
        return lagged_samples(i, lag), SimpleNamespace(sensor=None)

    readings = {
        i: (lagged_samples(i, recorded_lag), _result(*fits.get(i, ("none", None))))
        for i in range(n)
    }
    return readings, read, sheets


def test_the_lowpass_a_fit_misplaced_is_profiled_by_the_law_and_undone_on_every_recording(
    cubic_stand_in,
):
    """One rejected fit read the low-pass at 180 Hz (order 2): the corners searched from 90 Hz
    to 0.45 fs, the law's best at the sensor's 250 Hz, and every recording read there."""
    low = {"lowpass_hz": 180.0, "lowpass_order": 2}
    readings, read, sheets = campaign({2: ("rejected", low)})
    out, info = profiled_lowpass(read, readings, [1000.0] * 4)
    assert info is not None
    assert info["lowpass_hz"] == pytest.approx(SENSOR_HZ, rel=0.05)
    assert info["lowpass_order"] == 2.0 and info["seen_hz"] == 180.0
    assert info["unexplained"] <= MAX_UNEXPLAINED_RATIO * info["unexplained_recorded"]
    corners = [c for c, _ in info["profile"]]
    assert min(corners) == pytest.approx(90.0) and max(corners) == pytest.approx(450.0)
    final = [s for s in sheets if s["lowpass_hz"] == info["lowpass_hz"]]
    assert len(final) >= 4 and all(s["resonance_hz"] == 0 and s["highpass_hz"] == 0 for s in final)
    assert sorted(out) == list(range(4)) and all(out[i] is not readings[i] for i in out)


def test_the_law_reads_the_lag_a_lowpass_leaves():
    """What the profile minimises: the share of the force the discovered law leaves, which a
    force late on the penetration raises (a loop no static law follows)."""
    late = law_unexplained([lagged_samples(i, 0.12) for i in range(4)])
    on_time = law_unexplained([lagged_samples(i, 0.0) for i in range(4)])
    assert on_time < 0.01 * late


@pytest.mark.parametrize(
    "fits",
    [
        {},  # no fit at all: nothing was seen
        {2: ("rejected", {"resonance_hz": 240.0, "resonance_damping": 0.04})},  # a mount alone
        {2: ("kept", {"lowpass_hz": 180.0, "lowpass_order": 2})},  # a chain kept: its own rule
    ],
)
def test_no_lowpass_seen_or_a_chain_kept_reads_the_records_as_they_were(fits, cubic_stand_in):
    readings, read, sheets = campaign(fits)
    out, info = profiled_lowpass(read, readings, [1000.0] * 4)
    assert info is None and out is readings and not sheets


def test_a_lowpass_whose_inverse_does_not_clearly_help_is_refused(cubic_stand_in):
    """The records as recorded are already read well (no lag): no corner halves what the law
    leaves unexplained, so they stay as recorded (the sheets read for the profile only)."""
    readings, read, sheets = campaign({0: ("rejected", {"lowpass_hz": 180.0})}, recorded_lag=0.0)
    out, info = profiled_lowpass(read, readings, [1000.0] * 4)
    assert info is None and out is readings and sheets


def test_seen_lowpass_takes_the_lowest_corner_and_the_common_order():
    results = [_result("rejected", {"lowpass_hz": 216.0, "lowpass_order": 2}),
               _result("rejected", {"lowpass_hz": 140.0, "lowpass_order": 2}),
               _result("rejected", {"lowpass_hz": 300.0, "lowpass_order": 4}),
               _result("none")]  # fmt: skip
    assert seen_lowpass(results) == {"lowpass_hz": 140.0, "lowpass_order": 2.0}
    assert seen_lowpass([*results, _result("kept", {"lowpass_hz": 250.0})]) is None
