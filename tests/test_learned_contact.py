"""The ``learned_contact`` effect: the discovered law in the simulator, its YAML, its listing."""

from __future__ import annotations

import json

import numpy as np
import pytest
import unknown_contact_laws as laws
import yaml
from typer.testing import CliRunner

from stiffnet.cli import app
from stiffnet.config import load_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.effects.learned_contact import LearnedContact, learned_contact_force, scaled_face
from stiffnet.effects.registry import build_effect
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.simulator import Simulator

BATCH = OscillatorBatch(beta=[8.0, 45.0], gap=[2.8, 2.4], amplitude=[1.9, 1.7],
                        omega=[1.05, 1.08], damping=[0.02, 0.02])  # fmt: skip


def run(effect):
    sim = Simulator([effect], settle_tolerance=0.2, min_transient_periods=5.0, substeps=4)
    return sim.simulate(BATCH, 100.0, 1500, rng=1)


def test_same_motion_as_the_user_two_stage_and_hunt_crossley_laws():
    a = run(laws.TwoStageContact(knee=0.1, ratio=4.0)).accel
    b = run(LearnedContact(knee=0.1, knee_ratio=4.0)).accel
    np.testing.assert_allclose(a, b, atol=1e-9 * np.abs(a).max())
    a = run(laws.HuntCrossleyContact(c=0.3)).accel
    b = run(LearnedContact(hunt_crossley=0.45)).accel
    np.testing.assert_allclose(a, b, atol=1e-9 * np.abs(a).max())
    assert np.abs(b).max() > 1.0  # there were impacts


def test_neutral_law_is_the_linear_restraint():
    lin = Simulator([], settle_tolerance=0.2, min_transient_periods=5.0).simulate(
        BATCH, 100.0, 1500, rng=1
    )
    learned = run(LearnedContact())
    # the numerical engine (RK4, 4 substeps per sample) against the exact closed form
    np.testing.assert_allclose(learned.accel, lin.accel, atol=2e-3 * np.abs(lin.accel).max())


def test_law_force_definition_of_beta():
    d = np.array([0.0, 0.05, 0.3, 0.6])
    v = np.zeros(4)
    p = {"exponent": 1.0, "reference_penetration": 0.3, "knee": 0.1, "knee_ratio": 3.0,
         "preload": 0.0, "hunt_crossley": 0.0, "damping_ratio": 0.0}  # fmt: skip
    # a linear leading term: beta is the slope at first touch; the second stage adds 2 beta
    np.testing.assert_allclose(learned_contact_force(d, v, 10.0, p), [0, 0.5, 7.0, 16.0])
    p.update(exponent=2.0, knee=10.0)
    # a power law: beta is the secant stiffness at d_r
    assert learned_contact_force(np.array([0.3]), np.zeros(1), 10.0, p)[0] == pytest.approx(3.0)
    # the restraint never pulls: strong dissipation while leaving clips the force at zero
    p.update(exponent=1.0, hunt_crossley=5.0)
    assert learned_contact_force(np.array([0.2]), np.array([-1.0]), 10.0, p)[0] == 0.0


def test_config_yaml_round_trip_and_effects_listing(tmp_path):
    text = """
effects:
  - name: learned_contact
    params: {exponent: 1.0, knee: 0.2, knee_ratio: 3.0, hunt_crossley: 0.45}
"""
    path = tmp_path / "c.yaml"
    path.write_text(text)
    cfg = load_config(SimulationConfig, path)
    eff = cfg.effects[0].build()
    assert isinstance(eff, LearnedContact) and eff.params.knee_ratio == 3.0
    again = yaml.safe_load(yaml.safe_dump(cfg.model_dump(mode="json")))
    assert again["effects"][0]["params"]["hunt_crossley"] == 0.45
    assert build_effect("learned_contact", {"knee_ratio": 2.0}).params.knee_ratio == 2.0
    res = CliRunner().invoke(app, ["effects", "--json", str(tmp_path / "e.json")])
    assert res.exit_code == 0, res.output
    names = {e["name"] for e in json.loads((tmp_path / "e.json").read_text())}
    assert "learned_contact" in names


def test_a_face_with_its_own_mass_moves_as_the_user_sprung_face():
    # the user's face: mass 0.3, ringing at 12 natural frequencies, loss factor 0.2, i.e.
    # support stiffness 0.3 * 12**2 = 43.2 and damping ratio 0.1
    a = run(laws.SprungFaceContact(m_f=0.3, f_face=12.0, eta=0.2)).accel
    eff = LearnedContact(face_mass=0.3, face_stiffness=43.2, face_damping=0.1)
    assert eff.n_states == 2 and LearnedContact().n_states == 0
    b = run(eff).accel
    np.testing.assert_allclose(a, b, atol=1e-9 * np.abs(a).max())
    # the face changes the motion (it is not the rigid restraint)
    c = run(LearnedContact()).accel
    assert np.abs(c - b).max() > 0.1 * np.abs(b).max()


def test_a_face_in_the_config_yaml(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(
        "effects:\n  - name: learned_contact\n"
        "    params: {face_mass: [0.22, 0.37], face_stiffness: 43.0, face_damping: 0.1}\n"
    )
    eff = load_config(SimulationConfig, path).effects[0].build()
    assert eff.n_states == 2 and eff.params.face_stiffness == 43.0
    with pytest.raises(Exception, match="face_mass"):
        LearnedContact(face_mass=-0.1)


def test_refit_space_of_a_law_with_a_face_holds_every_discovered_value():
    law = {"face_mass": 0.3, "face_stiffness": 43.0, "face_damping": 0.1,
           "reference_penetration": 0.2, "preload": 0.01, "damping_ratio": 0.05}  # fmt: skip
    space = LearnedContact.fit_space_at(law, 2000.0)
    assert space.names == ["face_mass", "face_stiffness", "face_damping"]
    assert space.multimodal == ("face_stiffness",)  # the face's ringing frequency
    lows = {fp.name: (fp.low, fp.high) for fp in space.free}
    assert lows["face_mass"] == pytest.approx((0.2, 0.45))
    assert lows["face_stiffness"] == pytest.approx((43.0 / 1.5, 43.0 * 1.5))
    assert lows["face_damping"] == pytest.approx((0.1 / 2.25, 0.1 * 2.25))
    # nothing the refit does not move goes back to the class defaults
    back = space.params(space.unit(law))
    assert back == pytest.approx({**LearnedContact().params.model_dump(), **law})
    assert back["reference_penetration"] == 0.2 and back["preload"] == 0.01


def test_refit_space_without_a_face_frees_only_the_terms_the_law_has():
    space = LearnedContact.fit_space_at({"knee": 0.2, "knee_ratio": 3.0, "exponent": 1.0}, 2e3)
    assert space.names == ["knee", "knee_ratio"] and space.multimodal == ()
    assert space.fixed["face_mass"] == 0.0 and space.fixed["hunt_crossley"] == 0.0
    # the blind space (diagnose --only learned_contact) is the class's shape terms
    assert LearnedContact.campaign_fit_space(2e3).names == [
        "exponent", "knee", "knee_ratio", "hunt_crossley"]  # fmt: skip


def test_a_library_effect_refit_keeps_values_its_space_does_not_fit():
    from stiffnet.effects.base import Effect
    from stiffnet.effects.registry import effect_class

    cls = effect_class("contact_damping")
    assert cls.fit_space_at({"damping_ratio": 0.2}, 2e3) == cls.campaign_fit_space(2e3)
    # the base rule (what any effect inherits): the class space, a given value it lacks held
    space = Effect.fit_space_at.__func__(LearnedContact, {"face_mass": 0.3}, 2e3)
    assert space.fixed["face_mass"] == 0.3 and "face_mass" not in space.names


#: A cantilever of mass 0.4 whose first mode rings at 10 natural frequencies: each mode's
#: tip mass a quarter of the beam's, the second at (4.6941 / 1.8751)**2 = 6.267 times the first.
TIP_MASS, W1, W2 = 0.1, 10.0, 10.0 * (4.6940911 / 1.8751041) ** 2
TWO_MODES = {"face_mass": TIP_MASS, "face_stiffness": TIP_MASS * W1**2,
             "face_damping": 0.05, "face2_mass": TIP_MASS,
             "face2_stiffness": TIP_MASS * W2**2, "face2_damping": 0.05}  # fmt: skip


def test_a_face_with_two_modes_moves_as_the_user_beam_tip():
    a = run(laws.BeamTipContact(m_b=0.4, f_1=10.0, zeta=0.05)).accel
    eff = LearnedContact(**TWO_MODES)
    assert eff.n_states == 4
    b = run(eff).accel
    np.testing.assert_allclose(a, b, atol=1e-9 * np.abs(a).max())
    # the second mode matters: the first alone moves the mass otherwise (23 % of the peak)
    one = {k: v for k, v in TWO_MODES.items() if not k.startswith("face2")}
    c = run(LearnedContact(**one)).accel
    assert np.abs(c - b).max() > 0.1 * np.abs(b).max()


def test_a_free_two_mode_face_rings_at_its_modal_frequencies():
    """Released (no contact force), the face's states evolve by a linear map whose
    eigenvalues are each mode's ``-zeta w +- i w sqrt(1 - zeta**2)``; its recoil is their sum."""
    eff = LearnedContact(**TWO_MODES)
    p = {k: np.asarray(v, float) for k, v in eff.params.model_dump().items()}
    jac = np.stack([eff.state_derivative(0.0, e[None], np.zeros(1), p)[0] for e in np.eye(4)], 1)
    lam = np.linalg.eigvals(jac)
    np.testing.assert_allclose(np.sort(np.abs(lam.imag))[::2], [W1 * np.sqrt(1 - 0.05**2),
                               W2 * np.sqrt(1 - 0.05**2)], rtol=1e-12)  # fmt: skip
    np.testing.assert_allclose(np.sort(-lam.real)[::2], [0.05 * W1, 0.05 * W2], rtol=1e-12)
    s = np.array([[0.3, 0.0, -0.1, 0.0]])
    assert eff.restraint_position(s, p)[0] == pytest.approx(0.2)


def test_no_second_mode_is_the_one_mode_face_bit_for_bit():
    one = {k: v for k, v in TWO_MODES.items() if not k.startswith("face2")}
    a = run(LearnedContact(**one)).accel
    b = run(LearnedContact(**one, face2_stiffness=500.0, face2_mass=0.0)).accel
    assert LearnedContact(**one, face2_mass=0.0).n_states == 2
    np.testing.assert_array_equal(a, b)


def test_shortcuts_of_a_law_without_power_preload_or_dissipation_are_the_same_numbers():
    from stiffnet.effects.learned_contact import elastic_shape, leading_term

    delta = np.array([-0.1, 0.0, 0.05, 0.3, 1.2])
    linear = {"exponent": np.ones(5), "reference_penetration": np.full(5, 0.5),
              "knee": np.full(5, 0.25), "knee_ratio": np.full(5, 2.5),
              "preload": np.zeros(5), "hunt_crossley": np.zeros(5)}  # fmt: skip
    # the general formula, written out: d_r (d / d_r)^p where p != 1, stage, preload
    d = np.maximum(delta, 0.0)
    stage = 1.5 * np.maximum(d - 0.25, 0.0)
    np.testing.assert_array_equal(elastic_shape(delta, linear), d + stage)
    law = LearnedContact(knee=0.25, knee_ratio=2.5)
    beta = OscillatorBatch(beta=np.full(5, 30.0), gap=np.zeros(5), amplitude=np.ones(5),
                           omega=np.ones(5), damping=np.full(5, 0.02))  # fmt: skip
    np.testing.assert_array_equal(law.contact_dissipation(delta, -delta, linear, beta), 0.0)
    # one row with a power or a preload takes the general path for every row
    mixed = {**linear, "exponent": np.array([1.0, 1.0, 1.5, 1.5, 1.0]),
             "preload": np.array([0.0, 0.0, 0.0, 0.1, 0.0])}  # fmt: skip
    power = np.where(mixed["exponent"] == 1.0, d, 0.5 * (d / 0.5) ** mixed["exponent"])
    np.testing.assert_array_equal(leading_term(delta, mixed["exponent"], 0.5), power)
    # a preload is the restraint's compression before touch: the leading term carries on
    # from it, d_r ((d + d_0) / d_r)^p (d + d_0 where p = 1), in contact
    step = np.where(d > 0, mixed["preload"], 0.0)
    pre = np.where(d > 0, 0.5 * ((d + mixed["preload"]) / 0.5) ** mixed["exponent"], 0.0)
    expected = np.where(mixed["exponent"] == 1.0, power + stage + step, pre + stage)
    np.testing.assert_array_equal(elastic_shape(delta, mixed), expected)


#: A face that scales with beta: support 1.25 beta, so the contact is 5 beta in front of it
#: (1/(5 beta) + 1/(1.25 beta) = 1/beta); mass 0.1 at beta 20, as beta^(-1/3).
SCALED = {"face_mass": 0.1, "face_stiffness_ratio": 1.25, "face_mass_exponent": -1 / 3,
          "face_reference_beta": 20.0, "face_damping": 0.05}  # fmt: skip


def _one_row(i):
    return OscillatorBatch(beta=[BATCH.beta[i]], gap=[BATCH.gap[i]],
                           amplitude=[BATCH.amplitude[i]], omega=[BATCH.omega[i]],
                           damping=[BATCH.damping[i]])  # fmt: skip


def test_a_scaled_face_is_each_rows_own_face_behind_a_stiffer_contact():
    """Each row of a batch moves as the absolute face of its own beta (support r beta, mass
    mu (beta/beta_ref)^q) behind a contact of beta r/(r - 1), here written as a second stage
    from first touch (knee 0, ratio 5): the same physics, written once per campaign instead
    of once per recording."""
    eff = LearnedContact(**SCALED)
    assert eff.n_states == 3  # the face's two states and the row's beta
    # a short record: the stiff contact's chattering orbit is chaotic, and the two writings of
    # the force (5 beta delta, beta (delta + 4 delta)) differ in their last bits
    kw = {"settle_tolerance": 0.2, "min_transient_periods": 2.0, "substeps": 4}
    for i, beta in enumerate(BATCH.beta):
        scaled = Simulator([eff], **kw).simulate(_one_row(i), 20.0, 600, rng=1).accel[0]
        own = LearnedContact(face_mass=0.1 * (beta / 20.0) ** (-1 / 3),
                             face_stiffness=1.25 * beta, face_damping=0.05, knee=0.0,
                             knee_ratio=5.0)  # fmt: skip
        a = Simulator([own], **kw).simulate(_one_row(i), 20.0, 600, rng=1).accel[0]
        assert np.abs(a).max() > 1.0  # there were impacts
        np.testing.assert_allclose(scaled, a, atol=1e-6 * np.abs(a).max())
    # its static stiffness at the contact is beta: the contact and the support in series
    p = {k: np.asarray(v, float) for k, v in eff.params.model_dump().items()}
    contact, kappa, _ = scaled_face(np.array(BATCH.beta), p)
    np.testing.assert_allclose(1.0 / (1.0 / contact + 1.0 / kappa), BATCH.beta, rtol=1e-12)


def test_a_scaled_face_in_the_config_yaml(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("effects:\n  - name: learned_contact\n    params: " + json.dumps(SCALED) + "\n")
    eff = load_config(SimulationConfig, path).effects[0].build()
    assert eff.n_states == 3 and eff.params.face_stiffness_ratio == 1.25
    back = yaml.safe_load(yaml.safe_dump({"params": eff.params.model_dump()}))["params"]
    assert LearnedContact(**back).params == eff.params
    with pytest.raises(Exception, match="face_stiffness_ratio"):
        LearnedContact(face_mass=0.1, face_stiffness_ratio=0.8)  # a contact that pulls
    # the refit from a scaled law frees its ratio around it, not an absolute stiffness
    space = LearnedContact.fit_space_at(SCALED, 1000.0)
    free = {fp.name: fp for fp in space.free}
    assert "face_stiffness" not in free and free["face_stiffness_ratio"].low > 1.0


def test_a_scaled_faces_beta_scale_runs_it_at_that_share_of_the_rows_beta():
    """``face_beta_scale`` s: the law's beta is s times the row's (a manifest labelling the
    beam's tip alone, without the contact in front), in its contact, support and mass alike,
    and a refit sweeps it within the face's box; on an absolute face it changes nothing."""
    beta = np.array(BATCH.beta, float)
    p = {**LearnedContact().params.model_dump(), **SCALED}
    for got, want in zip(scaled_face(beta, {**p, "face_beta_scale": 0.8}),
                         scaled_face(0.8 * beta, p), strict=True):  # fmt: skip
        np.testing.assert_allclose(got, want, rtol=1e-12)
    contact, kappa, _ = scaled_face(beta, {**p, "face_beta_scale": 0.8})
    np.testing.assert_allclose(1.0 / (1.0 / contact + 1.0 / kappa), 0.8 * beta, rtol=1e-12)
    absolute = {**p, "face_stiffness_ratio": 0.0, "face_stiffness": 40.0}
    for got, want in zip(scaled_face(beta, {**absolute, "face_beta_scale": 0.8}),
                         scaled_face(beta, absolute), strict=True):  # fmt: skip
        np.testing.assert_array_equal(got, want)
    free = {fp.name: fp for fp in LearnedContact.fit_space_at(
        {**SCALED, "face_beta_scale": 0.9}, 1000.0).free}  # fmt: skip
    assert free["face_beta_scale"].low == pytest.approx(0.6)
    assert free["face_beta_scale"].high == pytest.approx(1.35)
    assert "face_beta_scale" not in {fp.name for fp in LearnedContact.fit_space_at(
        {"face_mass": 0.3, "face_stiffness": 40.0}, 1000.0).free}  # fmt: skip
