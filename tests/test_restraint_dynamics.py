"""The alarm's restraint-dynamics check (``stiffnet.uncertainty.restraint_dynamics``).

Constructed impacts for the statistic (a force with one peak, two humps with a known dip);
recordings of a face that rings (``tests/unknown_contact_laws.py``: a user effect, not
library code) read by the shipped predictor for the check end to end.
"""

from __future__ import annotations

import numpy as np
import pytest
import unknown_contact_laws as laws

from stiffnet.uncertainty.alarm_verdict import ALARM_WORDS
from stiffnet.uncertainty.restraint_dynamics import (
    RESTRAINT_DYNAMICS,
    RestraintDynamicsThresholds,
    impact_second_peak,
    restraint_dynamics_reasons,
    restraint_dynamics_thresholds,
    second_peak_share,
    with_restraint_dynamics_check,
)
from stiffnet.uncertainty.unseen_law import trained_law_kinds

FN = 9.48
#: One impact's force with two humps: heights 1.0 and 0.6, the dip between them at 0.2, so
#: the second peak rises 0.6 - 0.2 = 0.4 of the first above it.
TWO_HUMPS = np.array([0.5, 1.0, 0.5, 0.2, 0.4, 0.6, 0.3])


def test_one_peak_reads_zero_and_two_humps_read_their_dip():
    t = np.linspace(0, np.pi, 12)
    assert impact_second_peak(np.sin(t)) == 0.0
    assert impact_second_peak(np.sin(t) + 0.3 * np.cos(t)) == 0.0  # Kelvin-Voigt: one peak
    assert impact_second_peak(TWO_HUMPS) == pytest.approx(0.4)
    assert impact_second_peak(2.5 * TWO_HUMPS) == pytest.approx(0.4)  # over the peak force
    assert impact_second_peak(np.zeros(6)) == 0.0


def _map(impact_forces: list[np.ndarray], gap: int = 8):
    """Displacement and force of consecutive impacts (displacement > 0 on the force's
    samples, onset 0) with `gap` free-flight samples (displacement < 0, no force) between."""
    disp, force = [], []
    for f in impact_forces:
        disp += [-np.ones(gap), np.linspace(0.1, 1.0, f.size)]
        force += [np.zeros(gap), f]
    disp.append(-np.ones(gap))
    force.append(np.zeros(gap))
    return np.concatenate(disp), np.concatenate(force)


def test_the_median_over_impacts_is_read_and_short_or_few_impacts_are_not_judged():
    t = RestraintDynamicsThresholds(second_peak_min=0.08, min_impacts=4, min_samples_per_contact=6)
    one = np.sin(np.linspace(0.2, np.pi - 0.2, 7))
    out = second_peak_share(*_map([TWO_HUMPS] * 4 + [one]), 0.0, t)
    assert out == {"second_peak": pytest.approx(0.4), "second_peak_impacts": 0.8, "n_impacts": 5}
    assert second_peak_share(*_map([one] * 5), 0.0, t)["second_peak"] == 0.0
    # contacts too short to resolve two humps, or too few impacts: nothing is judged
    assert second_peak_share(*_map([one[:4]] * 8), 0.0, t) is None
    assert second_peak_share(*_map([TWO_HUMPS] * 3), 0.0, t) is None


def test_noise_on_a_library_law_stays_below_the_threshold():
    """Half-sine impacts of 20 samples with 2 % noise of the peak: noise humps are small."""
    rng = np.random.default_rng(3)
    pulse = np.sin(np.linspace(0, np.pi, 22)[1:-1])
    forces = [pulse * rng.uniform(0.8, 1.2) + rng.normal(0, 0.02, pulse.size) for _ in range(20)]
    out = second_peak_share(*_map(forces), 0.0)
    assert out is not None and out["second_peak"] < restraint_dynamics_thresholds().second_peak_min


def test_the_rule_fires_above_its_threshold_and_names_the_restraint():
    t = RestraintDynamicsThresholds(second_peak_min=0.08)
    assert restraint_dynamics_reasons({"second_peak": 0.05}, t) == []
    assert restraint_dynamics_reasons(None, t) == []
    (reason,) = restraint_dynamics_reasons({"second_peak": 0.3, "second_peak_impacts": 0.9}, t)
    assert "30%" in reason and "90%" in reason and "beam" in reason


def test_the_check_joins_the_alarm_and_a_model_trained_with_a_face_is_not_judged():
    rf = {"impact_peaks": {"second_peak": 0.4, "second_peak_impacts": 1.0, "n_impacts": 20}}
    alarm = with_restraint_dynamics_check(None, rf)
    assert alarm["flag"] and alarm["fired"] == [RESTRAINT_DYNAMICS]
    assert alarm["scores"][RESTRAINT_DYNAMICS] == 0.4
    assert ALARM_WORDS[RESTRAINT_DYNAMICS] in alarm["message"]
    calm = with_restraint_dynamics_check(None, {"impact_peaks": {"second_peak": 0.0}})
    assert not calm["flag"] and calm["scores"][RESTRAINT_DYNAMICS] == 0.0
    assert with_restraint_dynamics_check(None, {"impact_peaks": None}) is None  # not judged
    params = {"face_mass": [0.05, 0.2], "face_stiffness": 10.0}
    face = {"effects": [{"name": "learned_contact", "probability": 1.0, "params": params}]}
    seen = trained_law_kinds(face)
    assert RESTRAINT_DYNAMICS in seen
    assert with_restraint_dynamics_check(None, rf, seen) is None
    assert RESTRAINT_DYNAMICS not in trained_law_kinds({"effects": [{"name": "contact_damping"}]})


def test_the_shipped_thresholds_are_read_from_the_config():
    from stiffnet.config import load_yaml
    from stiffnet.shipped import default_config

    shipped = load_yaml(default_config("alarm/restraint_dynamics.yaml"))
    t = restraint_dynamics_thresholds()
    assert t.second_peak_min == shipped["second_peak_min"]
    assert t.min_samples_per_contact == shipped["min_samples_per_contact"]
    with pytest.raises(Exception, match="unknown_key"):
        RestraintDynamicsThresholds.model_validate({"unknown_key": 1.0})


def _recording(effects, beta: float, seed: int) -> np.ndarray:
    """30 natural periods at 105 samples each (the independent rig's 1 kHz at f_n 9.48 Hz),
    forced at the natural frequency, 2 % noise."""
    from stiffnet.simulator.batch import OscillatorBatch
    from stiffnet.simulator.simulator import Simulator

    batch = OscillatorBatch(
        beta=np.array([beta]), gap=np.array([1.6]), amplitude=np.array([1.5]),
        omega=np.array([1.0]), damping=np.array([0.02]),
    )  # fmt: skip
    res = Simulator(effects).simulate(batch, np.array([105.0]), 105 * 30, noise=0.02, rng=seed)
    return res.accel[0]


def test_the_shipped_predictor_alarms_on_a_face_that_rings_and_not_on_a_fixed_stop():
    """A linear contact on a face of a tenth of the mass ringing at 10 natural frequencies
    (user effect): the model reads the contact in series with the face's support, and the
    check fires; the same contact on a fixed stop does not fire it."""
    from serving.predictor import Predictor

    predictor = Predictor.load()
    face = [laws.SprungFaceContact(m_f=0.1, f_face=10.0, eta=0.04)]
    for effects, fires in ((face, True), ([], False)):
        out = predictor.predict(_recording(effects, 30.0, 1), 105 * FN, natural_frequency_hz=FN)
        peaks = out["restoring_force"]["impact_peaks"]
        assert peaks is not None
        assert (RESTRAINT_DYNAMICS in out["alarm"]["fired"]) is fires, peaks
        # clear of the threshold (0.08) either way: 0.18 on this face, 0 on the fixed stop
        assert peaks["second_peak"] >= 0.12 if fires else peaks["second_peak"] < 0.03
