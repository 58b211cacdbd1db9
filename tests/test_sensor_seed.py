"""diagnose's sensor_dynamics fit starts from the chain identified on the contact pulses.

The restoring-force evidence identifies the campaign's shared sensor chain
(:func:`stiffnet.restoring_force.chain.shared_chain`); the campaign target hands
it to the fit as ``sensor_<parameter>`` observations, the effect seeds its fit
there and searches an identified low-pass's corner (else fixed off).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from campaign_helpers import short_manifest

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.campaign.simulate import FIT_SETTINGS
from stiffnet.effects.sensor_dynamics import SensorDynamics
from stiffnet.measurement import fitting
from stiffnet.measurement.evidence import contact_evidence, contact_law_per_recording
from stiffnet.measurement.target import CampaignTarget, measured_statistics

CHAIN = {"resonance_hz": 237.0, "resonance_damping": 0.03, "lowpass_hz": 150.0,
         "lowpass_order": 2, "highpass_hz": 0.0}  # fmt: skip


def test_the_identified_chain_is_the_first_seed_and_its_lowpass_is_searched():
    rows = [SimpleNamespace(fs_hz=1000.0), SimpleNamespace(fs_hz=1250.0)]
    shared = {"n": 5, "resonance_hz": 230.0, "resonance_damping": 0.04, "lowpass_hz": 140.0,
              "lowpass_order": 3.0, "highpass_hz": None}  # fmt: skip
    target = CampaignTarget(list(rows), [], [], sensor=shared)
    observed = target.observed()
    assert observed == {"sensor_resonance_hz": 230.0, "sensor_resonance_damping": 0.04,
                        "sensor_lowpass_hz": 140.0, "sensor_lowpass_order": 3.0}  # fmt: skip
    space = fitting.effect_space("sensor_dynamics", rows, observed)
    corner = next(p for p in space.free if p.name == "lowpass_hz")
    assert corner.low == 70.0 and corner.high == pytest.approx(0.45 * 1000.0) and corner.log
    assert space.fixed == {"lowpass_order": 3.0}
    seeds = SensorDynamics.fit_seeds({**observed, "ringing_hz": 236.0}, space)
    assert seeds[0] == {"lowpass_order": 3.0, "lowpass_hz": 140.0, "resonance_hz": 230.0,
                        "resonance_damping": 0.04, "highpass_hz": 0.0}  # fmt: skip
    assert len(seeds) == 1 + 18 and all(s["lowpass_hz"] == 140.0 for s in seeds)
    point = space.params(space.unit(seeds[0]))
    assert point == pytest.approx(seeds[0])  # the seed is a point of the searched space
    # no chain: the space and the ringing seeds are as before (low-pass held off)
    bare = fitting.effect_space("sensor_dynamics", rows, {"ringing_hz": 236.0})
    assert bare == fitting.effect_space("sensor_dynamics", rows)
    assert bare.fixed["lowpass_hz"] == 0.0
    assert len(SensorDynamics.fit_seeds({"ringing_hz": 236.0}, bare)) == 18
    # a chain with only a resonance: no low-pass searched, the resonance seeded
    only = fitting.effect_space("sensor_dynamics", rows, {"sensor_resonance_hz": 230.0})
    assert only == bare
    assert SensorDynamics.fit_seeds({"sensor_resonance_hz": 230.0}, only)[0]["resonance_hz"] == 230


@pytest.fixture(scope="module")
def chained(tmp_path_factory):
    """5 recordings of 3 s through a mounted resonance and a 2nd-order low-pass at
    0.12-0.15 fs (no high-pass), the smallest campaign the diagnosis tests use."""
    tmp = tmp_path_factory.mktemp("chain")
    eff = "sensor_dynamics:" + ",".join(f"{k}={v}" for k, v in CHAIN.items())
    return load_campaign(simulate_campaign(short_manifest(tmp, 5), tmp / "c", [eff], seed=0))


@pytest.mark.slow
def test_a_campaign_through_a_known_chain_is_fitted_from_it(chained, monkeypatch):
    rows = list(chained.rows)
    measured, lengths, _ = measured_statistics(chained, rows, False)
    target = CampaignTarget(rows, measured, lengths, [], 0, False)
    without = fitting.fit_effect(target, "sensor_dynamics", settings=FIT_SETTINGS)
    # the chain as diagnose's evidence reads it (on 2 recordings: its fit costs seconds each)
    target.sensor = contact_evidence(contact_law_per_recording(chained, rows[:2]))["sensor"]
    seeds = []
    original = SensorDynamics.fit_seeds.__func__

    def spy(cls, observed, space):
        seeds.extend(original(cls, observed, space))
        return seeds

    monkeypatch.setattr(SensorDynamics, "fit_seeds", classmethod(spy))
    fit = fitting.fit_effect(target, "sensor_dynamics", settings=FIT_SETTINGS)
    chain = target.sensor
    assert seeds[0]["resonance_hz"] == chain["resonance_hz"]
    assert seeds[0]["lowpass_hz"] == chain["lowpass_hz"]
    assert chain["lowpass_hz"] == pytest.approx(150.0, rel=0.1)  # the identification
    p = fit["params"]
    for key in ("resonance_hz", "resonance_damping", "lowpass_hz"):
        assert p[key] == pytest.approx(CHAIN[key], rel=0.1), p
    assert p["lowpass_order"] == 2.0 and p["highpass_hz"] < 0.5
    # without the chain the fit holds the low-pass off and misreads the resonance's damping:
    # the chain's start explains the campaign several times better
    assert without["params"]["lowpass_hz"] == 0.0
    assert np.mean(fit["per_recording"]) < 0.25 * np.mean(without["per_recording"])


@pytest.mark.slow
def test_a_seed_ten_percent_off_still_reaches_the_chain(chained):
    """The identified chain only starts the fit: from a damping and a low-pass 10 % off (a
    resonance 2 % off) the fit should reach the chain, and invent no high-pass."""
    rows = list(chained.rows)
    measured, lengths, _ = measured_statistics(chained, rows, False)
    target = CampaignTarget(rows, measured, lengths, [], 0, False)
    target.sensor = {"n": 5, "resonance_hz": 1.02 * CHAIN["resonance_hz"],
                     "resonance_damping": 1.1 * CHAIN["resonance_damping"],
                     "lowpass_hz": 1.1 * CHAIN["lowpass_hz"], "lowpass_order": 2.0,
                     "highpass_hz": None}  # fmt: skip
    p = fitting.fit_effect(target, "sensor_dynamics", settings=FIT_SETTINGS)["params"]
    assert p["resonance_hz"] == pytest.approx(CHAIN["resonance_hz"], rel=0.01), p
    assert p["resonance_damping"] == pytest.approx(CHAIN["resonance_damping"], rel=0.05), p
    assert p["lowpass_hz"] == pytest.approx(CHAIN["lowpass_hz"], rel=0.05), p
    assert p["highpass_hz"] < 0.2, p
