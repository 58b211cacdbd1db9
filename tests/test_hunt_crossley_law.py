"""Beta in a learned Hunt-Crossley law's sense: the map's elastic slope at first contact.

A model trained with a learned law whose dissipation grows with penetration
(``learned_contact`` with a ``hunt_crossley`` term) labels beta as that law's elastic slope at
first contact; the restoring-force check then reads the same quantity, the ``delta v`` term
fitted free (stiffnet.restoring_force.hunt_crossley_law). Recordings come from the independent
rig (tests/independent_rig.py: solve_ivp in SI units, its own Hunt-Crossley law).
"""

from __future__ import annotations

import numpy as np
import pytest
from independent_rig import RigRun, record

from serving.restoring_force_check import restoring_force_check, trained_penetration_dissipation
from stiffnet.restoring_force.contact_law import ContactLaw
from stiffnet.restoring_force.hunt_crossley_law import fit_hunt_crossley_law, hunt_crossley_force
from stiffnet.uncertainty.unseen_law import trained_law_kinds, unseen_law_reasons

BETA = 25.0
#: What a loop-trained model's card carries for the rig's Hunt-Crossley law (lambda 6 s/m).
CARD = {"effects": [{"name": "learned_contact", "probability": 1.0, "params": {
    "exponent": 1.0, "knee_ratio": 1.0, "hunt_crossley": [0.338, 0.374], "face_mass": 0.0,
    "face2_mass": 0.0, "reference_penetration": 0.37}}]}  # fmt: skip


@pytest.fixture(scope="module")
def hunt_crossley() -> tuple[np.ndarray, float]:
    """A 3-s independent-rig recording at 1 kHz of the loop's Hunt-Crossley campaign's first
    point (gap 2.8 mm, lambda 6 s/m, 2 % noise), beta 25."""
    run = RigRun(recording="hc.csv", beta=BETA, forcing_frequency_hz=9.95,
                 base_acceleration_g=0.757, gap_mm=2.8, duration_s=3.0,
                 contact="hunt_crossley", hc_lambda_s_per_m=6.0)  # fmt: skip
    _, accel = record(run, seed=5)
    return accel, run.fs_hz


def test_a_hunt_crossley_models_check_reads_the_elastic_slope_where_the_library_reads_high(
    hunt_crossley,
):
    accel, fs = hunt_crossley
    learned = restoring_force_check(accel, fs, 9.48, penetration_dissipation=True)
    library = restoring_force_check(accel, fs, 9.48)
    assert abs(learned["beta"] / BETA - 1) < 0.10, learned
    lo, hi = learned["beta_interval"]
    assert lo <= BETA <= hi and learned["class"] == "medium", learned
    assert learned["hunt_crossley"]["dissipation_share"] > 0.8, learned["hunt_crossley"]
    assert "Hunt-Crossley" in learned["reason"]
    # the spring and dashpot alone start late and read a steeper spring
    assert library["beta"] > 1.3 * BETA and library["hunt_crossley"] is None, library
    # judged against the law the model knows, the map shows nothing unseen; the library's
    # late onset leaves the force before it, read as a soft first stage
    seen = trained_law_kinds(CARD)
    assert unseen_law_reasons(learned, seen=seen) == []
    assert any("before the fitted law's onset" in r for r in unseen_law_reasons(library, seen=seen))


def test_a_map_that_needs_a_power_law_keeps_the_librarys_reading():
    """A two-stage restraint (knee 0.25 mm, ratio 2.5) reads as a power law: a law with a
    linear leading term, as the model's, would read its stiff stage; the library's reading is
    kept (the contact_law check judges the exponent)."""
    run = RigRun(recording="two_stage.csv", beta=19.0, forcing_frequency_hz=10.24,
                 base_acceleration_g=0.718, gap_mm=2.4, fs_hz=2000.0, duration_s=3.0,
                 contact="two_stage", knee_mm=0.25, stage_ratio=2.5)  # fmt: skip
    _, accel = record(run, seed=3)
    learned = restoring_force_check(accel, run.fs_hz, 9.48, penetration_dissipation=True)
    library = restoring_force_check(accel, run.fs_hz, 9.48)
    assert learned["exponent"] > 1.2 and learned["hunt_crossley"] is None, learned
    assert learned["beta"] == library["beta"]


def test_the_fit_recovers_a_known_law_and_finds_no_dissipation_term_on_a_kelvin_voigt_one():
    """Noisy half-sine impacts on ``K d (1 + a v) + c v``: the slope within 2 % and ``a``
    within 10 %; on a Kelvin-Voigt law (``a = 0``) the term carries almost none of the
    dissipation and the slope is the same."""
    rng = np.random.default_rng(0)
    t = np.linspace(0, np.pi, 16)[1:-1]
    for a, c in ((0.8, 0.0), (0.0, 8.0)):
        d = np.concatenate([np.sin(t) * (1 + 0.05 * rng.normal()) for _ in range(20)])
        v = np.tile(np.cos(t), 20)
        f = hunt_crossley_force(d, v, 50.0, 0.0, c, a)
        f = f + rng.normal(0, 0.01 * f.max(), f.size)
        start = ContactLaw(stiffness=70.0, onset=0.05, damping=5.0, exponent=1.0,
                           reference_penetration=1.0, r2=0.9)  # fmt: skip
        law = fit_hunt_crossley_law(f, d, v, np.ones(f.size, bool), start)
        assert law.stiffness == pytest.approx(50.0, rel=0.02)
        if a:
            assert law.dissipation == pytest.approx(a, rel=0.10)
        else:
            assert law.dissipation_share < 0.1, law


@pytest.mark.parametrize(
    "params, expected",
    [
        ({"exponent": 1.0, "hunt_crossley": [0.338, 0.374]}, True),
        ({"exponent": 1.0, "hunt_crossley": 0.5, "knee_ratio": 1.0}, True),
        ({"exponent": 1.0, "hunt_crossley": 0.0}, False),  # a Kelvin-Voigt law at most
        ({"exponent": 1.4, "hunt_crossley": 0.5}, False),  # beta at d_r: needs the gain
        ({"hunt_crossley": 0.5, "face_mass": 0.2}, False),  # the law acts on the face
    ],
)
def test_the_cards_learned_law_says_whether_its_dissipation_grows_with_penetration(
    params, expected
):
    learned = {"name": "learned_contact", "probability": 1.0, "params": params}
    priors = {"effects": [{"name": "contact_damping", "params": {}}, learned]}
    assert trained_penetration_dissipation(priors) is expected
    assert trained_penetration_dissipation({"effects": [{"name": "contact_damping"}]}) is False
    assert trained_penetration_dissipation(None) is False
    off = {**learned, "probability": 0.0}
    assert trained_penetration_dissipation({"effects": [off]}) is False
