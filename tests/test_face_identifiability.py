"""The face-identifiability check: beta behind a learned restraint face."""

import pytest

from serving.verdict import rule_checks, widened_interval
from stiffnet.uncertainty.face_identifiability import (
    face_beta_interval,
    face_class_share,
    face_compliances,
)

NAMES, EDGES = ["no_contact", "soft", "medium", "hard", "very_hard"], [5, 15, 35, 60, 100]


def priors(face_stiffness, **more):
    """A card's priors with the beam-tip loop's learned face (stiffness in the model's units)."""
    params = {"exponent": 1.0, "face_mass": [0.067, 0.111], "face_stiffness": face_stiffness,
              "face_damping": 0.026, "face2_mass": 0.0, "face2_stiffness": 1e3, **more}  # fmt: skip
    return {"effects": [{"name": "learned_contact", "probability": 1.0, "params": params}]}


BEAM = priors([8.4075, 14.0125])  # the beam-tip loop's GBM: the discovered 11.21 +- 25 %


def test_the_compliance_adds_the_modes_over_the_prior():
    low, mid, high = face_compliances(BEAM)
    assert (low, mid, high) == pytest.approx((1 / 14.0125, 1 / 11.21, 1 / 8.4075))
    two = face_compliances(priors(10.0, face2_mass=0.05, face2_stiffness=20.0))
    assert two == pytest.approx((0.15, 0.15, 0.15))
    assert face_compliances(priors(10.0, face_mass=0.0)) is None
    assert face_compliances(None) is None
    assert face_compliances({"effects": [{"name": "contact_damping", "params": {}}]}) is None


def test_a_face_that_scales_with_beta_is_not_judged():
    # m5's scaled face (support 1.27 beta, contact 4.76 beta): beta is the series stiffness
    # itself, and the law's absolute face_stiffness (100, unused) is no support to read
    scaled = priors(100.0, face_stiffness_ratio=[1.14, 1.39], face_mass_exponent=-0.73)
    assert face_compliances(scaled) is None
    assert face_class_share("medium", [9.7, 45.8], scaled, NAMES, EDGES) is None
    shared = priors([50.0, 200.0], face_stiffness_ratio=0.0)
    assert face_compliances(shared) == pytest.approx((1 / 200, 2 / 250, 1 / 50))


def test_a_face_known_exactly_keeps_the_models_interval():
    # one stiffness: the series stiffness maps back to the same beta
    c = 1 / 11.21
    assert face_beta_interval([20.0, 40.0], (c, c, c), 100.0) == pytest.approx([20.0, 40.0])


def test_the_classes_above_the_face_are_indistinguishable():
    # beta 38 read 15.0 "medium" [9.7, 45.8] on the rig's beam (wrong, no alarm before): at the
    # prior's softest face, the top of that interval leaves beta unbounded above
    share, wide = face_class_share("medium", [9.7, 45.8], BEAM, NAMES, EDGES)
    assert share > 0.5 and wide[1] == 100.0 and wide[0] < 9.7
    # beta 75 read 58.6 "hard" [37.6, 91.4]; beta 19 read 15.3 "soft" [9.8, 23.9]
    assert face_class_share("hard", [37.6, 91.4], BEAM, NAMES, EDGES)[0] > 0.5
    assert face_class_share("soft", [9.8, 23.9], BEAM, NAMES, EDGES)[0] > 0.5
    # a soft contact well below the face's stiffness stays identifiable: beta 9 read 8.7
    share, wide = face_class_share("soft", [4.1, 13.6], BEAM, NAMES, EDGES)
    assert share < 0.5 and wide[1] < 35
    # no face, no interval, no contact class: not judged
    assert face_class_share("medium", [9.7, 45.8], None, NAMES, EDGES) is None
    assert face_class_share("medium", None, BEAM, NAMES, EDGES) is None
    assert face_class_share("no_contact", [9.7, 45.8], BEAM, NAMES, EDGES) is None


def test_the_alarm_fires_and_the_flagged_interval_spans_what_the_face_allows():
    model = {"class_names": NAMES, "class_edges": EDGES, "priors": BEAM}
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    alarm = rule_checks(quiet, "medium", [9.7, 45.8], None, model, 1000.0, 9.48)
    assert alarm["fired"] == ["face_identifiability"]
    assert "not identifiable" in alarm["message"]
    wide, said = widened_interval([9.7, 45.8], None, model)
    assert wide[0] < 9.7 and wide[1] == 100.0 and "learned face" in said
    calm = rule_checks(quiet, "soft", [4.1, 13.6], None, model, 1000.0, 9.48)
    assert not calm["flag"] and calm["scores"]["face_identifiability"] < 0.5
    # the same answers from a model without a face: nothing judged, nothing widened
    plain = {**model, "priors": None}
    out = rule_checks(quiet, "medium", [9.7, 45.8], None, plain, 1e3, 9.48)
    assert not out["flag"] and "face_identifiability" not in out["scores"]
    assert widened_interval([9.7, 45.8], None, plain) == ([9.7, 45.8], None)
