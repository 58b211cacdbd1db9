"""Beta in a learned two-stage law's sense: the restoring-force map's first-stage slope.

A model trained with a learned two-stage law (``learned_contact`` with a ``knee_ratio``)
labels beta as the law's elastic slope at first contact; the restoring-force check then
reads the same quantity (stiffnet.restoring_force.staged_law). Recordings come from the
independent rig (tests/independent_rig.py: solve_ivp in SI units, its own two-stage law).
"""

from __future__ import annotations

import numpy as np
import pytest
from independent_rig import RigRun, record

from serving.restoring_force_check import restoring_force_check, trained_stage_ratio
from stiffnet.restoring_force.contact_law import ContactLaw
from stiffnet.restoring_force.staged_law import fit_staged_law, staged_force

BETA = 19.0
#: The ratio range a loop-trained model's card carries for a rig of ratio 2.5.
CARD_RATIO = (2.31, 2.56)


def _rig(knee_mm: float) -> tuple[np.ndarray, float]:
    """A 3-s independent-rig recording at 2 kHz: beta 19, ratio 2.5 beyond ``knee_mm``
    (the peak penetration is about 0.7 mm), 2 % noise."""
    run = RigRun(recording="two_stage.csv", beta=BETA, forcing_frequency_hz=10.24,
                 base_acceleration_g=0.718, gap_mm=2.4, fs_hz=2000.0, duration_s=3.0,
                 contact="two_stage", knee_mm=knee_mm, stage_ratio=2.5)  # fmt: skip
    _, accel = record(run, seed=3)
    return accel, run.fs_hz


@pytest.fixture(scope="module")
def two_stage() -> tuple[np.ndarray, float]:
    return _rig(0.25)


def test_the_first_stage_slope_is_read_where_the_library_reads_between_the_stages(two_stage):
    accel, fs = two_stage
    staged = restoring_force_check(accel, fs, 9.48, stage_ratio=CARD_RATIO)
    library = restoring_force_check(accel, fs, 9.48)
    assert abs(staged["beta"] / BETA - 1) < 0.10, staged
    lo, hi = staged["beta_interval"]
    assert lo <= BETA <= hi and staged["class"] == "medium", staged
    assert staged["stage"]["resolved"] and 0.1 < staged["stage"]["knee_fraction"] < 0.9, staged
    assert staged["stage"]["beyond_knee_interval"] is None
    # one slope across both stages: neither stage's (about 1.9x here)
    assert library["beta"] > 1.5 * BETA and library["stage"] is None, library


@pytest.mark.parametrize("knee_mm, covered", [(5.0, "beta"), (0.01, "beyond_knee_interval")])
def test_a_map_without_a_knee_reads_one_slope_and_says_what_it_cannot_exclude(knee_mm, covered):
    """Impacts all short of the knee (5 mm) or all beyond it (0.01 mm: below the first
    sample) show one slope. It is read as impacts short of the knee (right for 5 mm); the
    reading had every impact been beyond it is reported beside (right for 0.01 mm)."""
    accel, fs = _rig(knee_mm)
    rf = restoring_force_check(accel, fs, 9.48, stage_ratio=CARD_RATIO)
    stage = rf["stage"]
    assert stage["resolved"] is False and "short of the knee" in rf["reason"], rf
    beyond = stage["beyond_knee_interval"]
    assert rf["beta_interval"][0] / beyond[0] == pytest.approx(CARD_RATIO[1], rel=1e-9)
    lo, hi = rf["beta_interval"] if covered == "beta" else beyond
    assert lo <= BETA <= hi, rf
    if covered == "beta":
        assert abs(rf["beta"] / BETA - 1) < 0.10, rf


def test_the_staged_fit_recovers_a_known_law_and_tells_one_slope_apart():
    """Noisy samples of half-sine impacts on the law ``K (d + 1.5 (d - 0.4)+)``: the slope
    within 2 %, the knee within 5 %; impacts that stay short of the knee give one slope."""
    rng = np.random.default_rng(0)
    t = np.linspace(0, np.pi, 14)[1:-1]
    for peak, resolved in ((1.0, True), (0.3, False)):
        d = np.concatenate([peak * np.sin(t) * (1 + 0.05 * rng.normal()) for _ in range(20)])
        v = np.concatenate([peak * np.cos(t) for _ in range(20)])
        f = staged_force(d, v, 50.0, 0.0, 0.0, 0.4, 2.5)
        f = f + rng.normal(0, 0.01 * f.max(), f.size)
        near = np.ones(f.size, bool)
        start = ContactLaw(stiffness=60.0, onset=0.0, damping=0.0, exponent=1.0,
                           reference_penetration=peak, r2=0.9)  # fmt: skip
        law = fit_staged_law(f, d, v, near, start, 2.5, peak)
        assert law.resolved is resolved
        assert law.stiffness == pytest.approx(50.0, rel=0.02)
        if resolved:
            assert law.knee == pytest.approx(0.4, rel=0.05)


@pytest.mark.parametrize(
    "params, expected",
    [
        ({"exponent": 1.0, "knee_ratio": [2.31, 2.56], "knee": [0.24, 0.26]}, (2.31, 2.56)),
        ({"exponent": 1.0, "knee_ratio": 3.0}, (3.0, 3.0)),
        ({"exponent": 1.0, "knee_ratio": 1.0}, None),  # no second stage
        ({"exponent": 1.4, "knee_ratio": 2.0}, None),  # beta at d_r: needs the record's gain
        ({"knee_ratio": 2.0, "face_mass": 0.2}, None),  # the law acts on the face
    ],
)
def test_the_cards_learned_law_gives_the_stage_ratio(params, expected):
    learned = {"name": "learned_contact", "probability": 1.0, "params": params}
    priors = {"effects": [{"name": "contact_damping", "params": {}}, learned]}
    assert trained_stage_ratio(priors) == expected
    assert trained_stage_ratio({"effects": [{"name": "contact_damping"}]}) is None
    assert trained_stage_ratio(None) is None
