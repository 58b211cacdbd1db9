"""A face the maps cannot decide on: the rule that sends it to the simulation, its grid, and
the betas read behind a chosen face (samples written from a known face, analytic checks)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stiffnet.discovery import ContactSamples, DiscoveredLaw
from stiffnet.discovery.face import face_response, layout
from stiffnet.discovery.face_candidate import (
    GRID_FREQUENCIES,
    GRID_MASSES,
    betas_behind_face,
    face_grid,
    face_in_question,
    series_betas,
)
from stiffnet.discovery.select import law_from_fit
from stiffnet.discovery.terms import fit_law, stack

BETAS = (8.0, 20.0, 45.0, 90.0)
FACE = {"face_mass": 0.1, "face_stiffness": 10.0, "face_damping": 0.02}


def _law(explained: float, last: dict | None, new: tuple = ()) -> DiscoveredLaw:
    path = [{"term": "linear", "entered": True, "explained_fraction": explained}]
    return DiscoveredLaw(
        terms=new, params={}, intervals={}, recordings=("a",), betas=(5.0,),
        beta_intervals=(None,), onsets=(0.0,), explained_fraction=explained,
        library_explained_fraction=explained, library_terms=(),
        path=path + ([last] if last else []), new_terms=new,
    )  # fmt: skip


def test_a_face_is_in_question_only_where_the_maps_see_dynamics_and_refuse_it():
    refused = {"term": "face", "entered": False, "explained_fraction": 0.78}
    assert face_in_question(_law(0.71, refused))  # the beam's tip: 71 % linear, face 78 %
    assert face_in_question(_law(0.71, {**refused, "term": "face2"}))
    # a law that explains the force, a face that explains no more, another refused term, or
    # a law with something new already: the maps decided
    assert not face_in_question(_law(0.95, refused))
    assert not face_in_question(_law(0.71, {**refused, "explained_fraction": 0.70}))
    assert not face_in_question(_law(0.71, {**refused, "term": "hinge"}))
    assert not face_in_question(_law(0.71, None))
    assert not face_in_question(_law(0.71, refused, new=("hinge",)))


def test_a_light_stiff_tip_the_maps_read_as_a_softer_spring_is_in_question():
    """The rig's tip of 0.3 m at 15 f_n behind a 2 Hz high-pass: the linear spring explains
    90.1 % of the force, its refused scaled face 90.7 %: the simulation decides."""
    refused = {"term": "face_scaled", "entered": False, "explained_fraction": 0.9065}
    assert face_in_question(_law(0.9010, refused))
    assert face_in_question(_law(0.94, {**refused, "term": "face", "explained_fraction": 0.945}))
    assert not face_in_question(_law(0.9010, {**refused, "term": "hinge"}))


def test_the_grid_spans_masses_and_frequencies_above_the_fastest_contact():
    """Each point rings at its multiple of sqrt(1 + max beta) (4 significant digits)."""
    grid = face_grid([4.0, 5.0, 8.0])
    assert len(grid) == len(GRID_MASSES) * len(GRID_FREQUENCIES)
    rates = sorted({round(np.sqrt(g["face_stiffness"] / g["face_mass"]) / 3.0, 3) for g in grid})
    assert rates == pytest.approx(sorted(GRID_FREQUENCIES), rel=1e-3)
    assert sorted({g["face_mass"] for g in grid}) == sorted(GRID_MASSES)


def test_series_betas_add_the_compliances():
    np.testing.assert_allclose(series_betas([10.0, 90.0], FACE), [5.0, 9.0])
    two = {**FACE, "face2_mass": 0.1, "face2_stiffness": 90.0}
    np.testing.assert_allclose(series_betas([10.0], two), [1 / (0.1 + 0.1 + 1 / 90)])
    np.testing.assert_allclose(series_betas([10.0], {"face_mass": 0.0}), [10.0])


def face_samples(face: dict, noise: float = 0.0, seed: int = 0) -> list[ContactSamples]:
    """Impacts of a linear contact on a face: half-sine penetrations ``delta`` (the contact's
    own), the force ``beta delta``, the face's recoil ``y`` under it (exact, from rest at each
    impact's first sample), the mass at ``x = e + delta + y``; the velocity such that
    ``dx = v dt`` holds by the trapezoid rule, as the discovery reads the interval (the recoil,
    4.5 times the penetration on the softest support, amplifies an interval read 0.3 % off
    into betas 7 % off)."""
    rng = np.random.default_rng(seed)
    out = []
    for r, beta in enumerate(BETAS):
        om = np.sqrt(1.0 + beta)
        t = np.linspace(-0.4, 1.4, 40) * np.pi / om
        dt = float(t[1] - t[0])
        n_imp = 12
        amp = 0.6 / np.sqrt(beta / 8.0) * rng.uniform(0.7, 1.3, n_imp)
        delta = (amp[:, None] * np.sin(om * t)).ravel()
        ddot = (amp[:, None] * om * np.cos(om * t)).ravel()
        f = beta * np.maximum(delta, 0.0)
        imp = np.repeat(np.arange(1, n_imp + 1), t.size)
        lay = layout(np.zeros(f.size, int), imp, 1)
        y, yd = face_response(f, lay, np.array([dt]), *face.values())
        x, v = 1.5 + delta + y, ddot + yd
        for k in range(1, x.size):  # the trapezoid rule within each impact
            if imp[k] == imp[k - 1]:
                v[k] = 2.0 * (x[k] - x[k - 1]) / dt - v[k - 1]
        fn = f + noise * f.max() * rng.standard_normal(f.size)
        out.append(ContactSamples(f"r{r}", x, v, fn, imp, 1.5, beta))
    return out


def test_the_betas_behind_the_true_face_are_the_contacts_own():
    """Behind the face that wrote the samples the linear spring reads each contact's beta
    (within 2 %); the linear spring on the raw maps reads less."""
    samples = face_samples(FACE)
    data = stack(samples)
    lin = fit_law(data, frozenset(), 0.3)
    plain = replace(law_from_fit(data, lin, [], lin), terms=("face",), new_terms=("face",))
    behind = betas_behind_face(samples, plain, FACE)
    np.testing.assert_allclose(behind.betas, BETAS, rtol=0.02)
    assert behind.explained_fraction > 0.999
    assert behind.params["face_stiffness"] == FACE["face_stiffness"]
    # the raw maps read the contact in series with the face's support, below its own
    assert all(b < t for b, t in zip(lin.betas, BETAS, strict=True))


def test_the_unknowns_name_the_nyquist_frequency_and_the_series_betas():
    """The slowest recording (1000 Hz at f_n 9.48 Hz) sees modes up to 52.7 natural
    frequencies; the series betas of 10 and 90 behind a support of 10 are 5 and 9."""
    from types import SimpleNamespace

    from stiffnet.measurement.face_by_simulation import face_unknowns

    rows = [SimpleNamespace(fs_hz=fs, natural_frequency_hz=9.48) for fs in (1000.0, 2000.0)]
    law = replace(_law(0.71, None), betas=(10.0, 90.0))
    words = face_unknowns(law, rows, FACE)
    assert len(words) == 3 and "52.7 natural frequencies" in words[1]
    assert "one mode at 10 natural frequencies" in words[1] and "= 5-9," in words[2]


def test_the_proposal_carries_the_face_with_its_series_betas_or_says_why_not():
    from types import SimpleNamespace

    from stiffnet.measurement.learned_law import _face_entries

    samples = face_samples(FACE)
    data = stack(samples)
    lin = fit_law(data, frozenset(), 0.3)
    plain = replace(law_from_fit(data, lin, [], lin), terms=("face",), new_terms=("face",))
    chosen = betas_behind_face(samples, plain, FACE)
    rows = [SimpleNamespace(fs_hz=1000.0, natural_frequency_hz=9.48)]
    face = {"significant": True, "law": chosen, "params": chosen.params, "model": 1}
    out = _face_entries(face, plain, samples, rows)
    assert out["law"]["terms"] == ["face"] and len(out["unknowns"]) == 3
    np.testing.assert_allclose(out["series_betas"], [1 / (1 / b + 0.1) for b in BETAS], rtol=0.02)
    assert "law" not in out["face_by_simulation"] and "summary" not in out
    first = {"significant": False, "term": "face_scaled",
             "significance": {"reasons": ["it removes 1 %"]}}  # fmt: skip
    refused = {"significant": False, "term": "face", "refused_first": first,
               "significance": {"reasons": ["it removes 5 %"]}}  # fmt: skip
    out = _face_entries(refused, plain, samples, rows)
    assert out["proposed"] is False
    assert out["summary"].endswith(
        "refused (a face that scales with beta: it removes 1 %; the rig's shared face: it "
        "removes 5 %)"
    )


def test_the_simulation_tries_the_scaled_face_only_where_it_refuses_the_shared_one(monkeypatch):
    """The shared face (three parameters) is simulated first; the scaled face only where the
    simulation refuses it, the refused account's entries kept beside the other's."""
    import stiffnet.measurement.face_by_simulation as fbs

    def simulated(significant):
        def run(term, *args):
            tried.append(term)
            return {"significant": significant[term], "term": term, "law": None}

        return run

    both = ["face", "face_scaled"]
    cases = [({"face": True, "face_scaled": True}, ["face"]),
             ({"face": False, "face_scaled": True}, both),
             ({"face": False, "face_scaled": False}, both)]  # fmt: skip
    for significant, order in cases:
        tried = []
        monkeypatch.setattr(fbs, "simulated_face", simulated(significant))
        out = fbs.face_by_simulation(*([None] * 8))
        assert tried == order and out["term"] == order[-1]
        assert ("refused_first" in out) == (len(order) == 2)
        if len(order) == 2:
            assert out["refused_first"] == {"significant": False, "term": "face"}
