"""The independent rig's beam that is the impacted material (``beam_material``): beta is the
cantilever's static tip stiffness, the beam's length sets it, and the tip is struck through a
stiff local contact. Analytic expectations of Euler-Bernoulli beam theory."""

from __future__ import annotations

import pytest
from independent_rig import (
    CANTILEVER_LAMBDA_L,
    MATERIAL_BEAM_REFERENCE_BETA,
    RigRun,
    cantilever_tip_modes,
    material_beam_tip_modes,
)


@pytest.mark.parametrize("beta", [8.0, 30.0, 90.0])
@pytest.mark.parametrize("n_modes", [1, 2, 3])
def test_the_modes_static_compliance_is_the_labelled_beta(beta, n_modes):
    # Each mode's tip compliance 1/(m_i w_i^2) is 12/(lambda_i L)^4 of 1/beta; all modes sum
    # to 1/beta exactly, the first three to 97.1 %, 99.55 % and 99.88 % of it.
    modes = material_beam_tip_modes(n_modes, 0.3, beta)
    compliance = sum(1.0 / (mu * r**2) for mu, r in modes)
    expected = sum(12.0 / li**4 for li in CANTILEVER_LAMBDA_L[:n_modes]) / beta
    assert compliance == pytest.approx(expected, rel=1e-12)
    assert beta * compliance == pytest.approx(1.0, abs=0.03)
    assert beta * compliance <= 1.0


def test_a_stiffer_beam_is_shorter_lighter_and_rings_higher():
    # mass ~ L ~ beta^(-1/3); w1 ~ L^-2 ~ beta^(2/3) at a fixed section
    soft, stiff = (material_beam_tip_modes(2, 0.3, b) for b in (10.0, 80.0))
    assert stiff[0][0] / soft[0][0] == pytest.approx(8.0 ** (-1 / 3), rel=1e-12)
    assert stiff[0][1] / soft[0][1] == pytest.approx(8.0 ** (2 / 3), rel=1e-12)
    # the modes' ratios are the cantilever's, whatever its length
    ratio = (CANTILEVER_LAMBDA_L[1] / CANTILEVER_LAMBDA_L[0]) ** 2
    assert soft[1][1] / soft[0][1] == pytest.approx(ratio, rel=1e-12)
    at_reference = material_beam_tip_modes(1, 0.3, MATERIAL_BEAM_REFERENCE_BETA)
    assert at_reference[0][0] == pytest.approx(0.075, rel=1e-12)


def test_the_run_strikes_its_own_beam_through_a_stiff_contact():
    run = RigRun("r.csv", 40.0, contact="beam", beam_material=True, beam_contact_ratio=25.0)
    assert run.contact_beta == 1000.0
    modes = run.tip_modes
    expected = material_beam_tip_modes(2, 0.3, 40.0)
    assert [m for m, _ in modes] == pytest.approx([m for m, _ in expected])
    assert [w for _, w in modes] == pytest.approx([r * run.omega_n for _, r in expected])
    # the contact in series with the beam: what the mass feels statically, near beta
    series = 1.0 / (1.0 / run.contact_beta + sum(1.0 / (m * (w / run.omega_n) ** 2)
                                                 for m, w in modes))  # fmt: skip
    assert series == pytest.approx(40.0 / (1 + 1 / 25.0 - 0.0045), rel=2e-3)


def test_the_shared_beam_keeps_beta_as_the_contact_behind_it():
    run = RigRun("r.csv", 40.0, contact="beam", beam_mass_ratio=0.4, beam_f1_ratio=10.0)
    assert run.contact_beta == 40.0
    expected = cantilever_tip_modes(2, 0.4, 10.0)
    assert [w for _, w in run.tip_modes] == pytest.approx([r * run.omega_n for _, r in expected])
    # the campaign's beam: the same modes whatever the contact's beta
    other = RigRun("r.csv", 80.0, contact="beam", beam_mass_ratio=0.4, beam_f1_ratio=10.0)
    assert other.tip_modes == run.tip_modes
