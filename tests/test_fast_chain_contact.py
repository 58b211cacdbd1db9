"""The contact_law check's fast-chain-contact rule: a fitted chain's contact pulse against the
fitted law's contact frequency (stiffnet.uncertainty.unseen_law.fast_chain_contact_reasons)."""

from __future__ import annotations

import pytest
from independent_rig import RigRun
from rig_predictions import LAB_MOUNT, predict_rig_run

from stiffnet.uncertainty.unseen_law import (
    STIFFENING,
    UnseenLawThresholds,
    chain_contact_ratio,
    fast_chain_contact_reasons,
    unseen_law_reasons,
    unseen_law_thresholds,
)

_FN = 9.48  # the independent rig's natural frequency (Hz)


def _sensor(contact_hz, resonance_hz=237.0, lowpass_hz=None, source="fitted", applied=True):
    return {"source": source, "resonance_hz": resonance_hz, "lowpass_hz": lowpass_hz,
            "applied": applied, "contact_hz": sum(contact_hz) / 2,
            "intervals": {"contact_hz": list(contact_hz)}}  # fmt: skip


def _rf(contact_hz, beta_interval, r2, **sensor):
    return {"exponent": 1.05, "contact_r2": r2, "contact_damping_ratio": 0.0,
            "duration_ratio": 1.1, "samples_per_contact": 9.0, "law_shape": {},
            "beta_interval": list(beta_interval), "sensor": _sensor(contact_hz, **sensor),
            "chain_contact_ratio": chain_contact_ratio(_sensor(contact_hz, **sensor),
                                                       list(beta_interval), _FN)}  # fmt: skip


def test_a_linear_contacts_pulse_and_law_agree():
    """A linear contact's pulse and law give one frequency: f_n sqrt(1 + beta)."""
    beta = 35.0
    f = _FN * (1 + beta) ** 0.5
    lo, hi = chain_contact_ratio(_sensor([0.97 * f, 1.03 * f]), [32.0, 38.0], _FN)
    assert lo < 1.0 < hi
    assert lo == pytest.approx(0.97 * f / (_FN * 39**0.5))
    assert hi == pytest.approx(1.03 * f / (_FN * 33**0.5))


@pytest.mark.parametrize(
    "sensor, interval",
    [
        (None, [30.0, 40.0]),
        (_sensor([57.8, 59.3], source="datasheet"), [30.0, 40.0]),  # a data sheet: no pulse fit
        (_sensor([57.8, 59.3], resonance_hz=None), [30.0, 40.0]),  # a high-pass alone
        ({**_sensor([57.8, 59.3]), "intervals": {}}, [30.0, 40.0]),
        (_sensor([57.8, 59.3]), None),
    ],
)
def test_no_ratio_without_a_fitted_chain_with_dynamics_or_an_interval(sensor, interval):
    assert chain_contact_ratio(sensor, interval, _FN) is None


@pytest.mark.parametrize(
    "contact_hz, beta_interval, r2, sensor, fires",
    [
        # bench_alarm's rig_two_stage_sensor draw 0 (offset 0): beta 36.3 read 93 by the model
        # and the map alike, no rule fired; the chain fit's pulse is 1.15-1.51 times as fast
        ((113.56, 129.17), (80.50, 107.44), 0.9992, {}, True),
        # ... and draw 0 at offset 1000 (beta 9.5 read 27): 1.003-1.15
        ((53.96, 56.63), (25.88, 31.20), 0.9993, {"lowpass_hz": 319.9}, True),
        # rig_sensor draw 0 (the same mount, a linear contact): 0.95-1.09
        ((57.76, 59.34), (31.71, 39.76), 0.9992, {}, False),
        # rig_sensor draw 5 at offset 1000: slower than its law (0.58-0.84), a right answer
        ((46.83, 60.02), (56.39, 72.76), 0.9992, {"resonance_hz": 234.6}, False),
        # sensor_dynamics draw 2 at offset 2000, right: 1.09-1.35 on a law of R2 0.990
        ((57.03, 62.19), (22.78, 29.40), 0.9902,
         {"resonance_hz": 297.1, "lowpass_hz": 245.6, "applied": False}, False),
    ],
)  # fmt: skip
def test_a_chain_pulse_faster_than_its_law_fires(contact_hz, beta_interval, r2, sensor, fires):
    t = UnseenLawThresholds(fast_chain_contact_min_ratio=1.0, fast_chain_contact_min_r2=0.995)
    rf = _rf(contact_hz, beta_interval, r2, **sensor)
    reasons = fast_chain_contact_reasons(rf, t)
    assert bool(reasons) is fires, rf["chain_contact_ratio"]
    if fires:
        assert reasons[0] in unseen_law_reasons(rf, t)
        assert "soft first stage" in reasons[0]
        assert f"{rf['chain_contact_ratio'][0]:.2f}" in reasons[0]
        # a model trained on a stiffening law is not told its law is unseen
        assert not set(reasons) & set(unseen_law_reasons(rf, t, seen=frozenset({STIFFENING})))


def test_the_rule_is_off_at_an_infinite_ratio():
    rf = _rf((113.56, 129.17), (80.50, 107.44), 0.9992)
    off = UnseenLawThresholds(fast_chain_contact_min_ratio=float("inf"))
    assert fast_chain_contact_reasons(rf, unseen_law_thresholds())
    assert not fast_chain_contact_reasons(rf, off)


@pytest.mark.slow  # two 8-s solve_ivp recordings and their cross-checks, ~25 s CPU
@pytest.mark.parametrize(
    "name, contact, fires",
    [
        ("rig_two_stage_sensor", dict(contact="two_stage", knee_mm=0.2, stage_ratio=3.0), True),
        ("rig_sensor", {}, False),
    ],
)
def test_the_independent_rigs_two_stage_law_behind_a_mount_is_faster_than_its_law(
    name, contact, fires
):
    """Draw 0 of bench_alarm's rig sets (seed 7, 8 s at 1 kHz): beta 36.3, forcing 1.085 f_n,
    behind the lab's mount. With the two-stage law the shipped model read "very_hard" (97)
    for "hard", the map a law of the stiff stage (93, exponent 1.53, in Hertz's band), and
    no other contact-law rule fired; the chain fit's pulse is faster than that law. The same
    draw with the paper's linear contact reads its law's frequency."""
    run = RigRun(recording=f"{name}_0.csv", beta=36.32123972011487,
                 forcing_frequency_hz=9.48 * 1.0845820701454363, noise=0.025513713804903866,
                 duration_s=8.0, sensor=LAB_MOUNT, **contact)  # fmt: skip
    res = predict_rig_run(run, seed=7)
    rf, t = res["restoring_force"], unseen_law_thresholds()
    assert rf["chain_contact_ratio"] is not None, rf["sensor"]
    reasons = fast_chain_contact_reasons(rf, t)
    assert bool(reasons) is fires, (rf["chain_contact_ratio"], rf["contact_r2"])
    assert ("contact_law" in res["alarm"]["fired"]) is fires
    if not fires:
        assert rf["chain_contact_ratio"][0] < 1.0 < rf["chain_contact_ratio"][1]
