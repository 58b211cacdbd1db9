"""Restoring-force evidence beside diagnose's fits: rules and a simulated damped campaign."""

from pathlib import Path

import numpy as np
import pytest

from stiffnet.campaign import load_campaign, read_manifest, simulate_campaign, write_manifest
from stiffnet.measurement.evidence import contact_evidence, restitution, restoring_force_evidence

ROOT = Path(__file__).resolve().parents[1]


def test_restitution_of_a_kelvin_voigt_contact():
    assert restitution(0.0) == 1.0
    assert restitution(0.5) == pytest.approx(np.exp(-np.pi * 0.5 / np.sqrt(0.75)))
    assert restitution(1.0) == 0.0


def _rec(zeta, p, ok=True):
    return {"recording": "r", "ok": ok, "contact_damping_ratio": zeta, "exponent": p}


def test_evidence_rules_name_dissipation_and_stiffening():
    damped = contact_evidence([_rec(0.3, 1.0), _rec(0.25, 1.0), _rec(0.2, 1.05)])
    assert damped["supports"] == ["contact_damping"]
    assert damped["contact_damping_ratio"] == pytest.approx(0.25)
    assert "supports contact_damping" in damped["summary"]
    hertz = contact_evidence([_rec(0.0, 1.5), _rec(0.01, 1.4), _rec(0.0, 1.6, ok=False)])
    assert hertz["supports"] == ["hertz_contact"] and hertz["answered"] == 2
    ideal = contact_evidence([_rec(0.01, 1.0), _rec(0.0, 1.0)])
    assert ideal["supports"] == [] and "no dissipation" in ideal["summary"]
    few = contact_evidence([_rec(0.3, 1.0), _rec(None, None, ok=False)])
    assert few["supports"] == [] and "too few" in few["summary"]


@pytest.mark.parametrize("zeta", [0.0, 0.25])
def test_evidence_on_a_simulated_campaign(tmp_path, zeta):
    """The hidden-effect manifest's 8 rows: dissipation named only when the contact has it."""
    effects = [f"contact_damping:damping_ratio={zeta}"] if zeta else []
    rows = read_manifest(ROOT / "examples" / "hidden_effect_manifest.csv")
    manifest = write_manifest(
        tmp_path / "m.csv", [r.model_copy(update={"duration_s": 2.0}) for r in rows]
    )
    camp = load_campaign(simulate_campaign(manifest, tmp_path / "c", effects, seed=0))
    ev = restoring_force_evidence(camp, camp.rows)
    assert ev["answered"] >= 6
    if zeta:
        assert ev["supports"] == ["contact_damping"]
        assert ev["contact_damping_ratio"] == pytest.approx(zeta, abs=0.08)
    else:
        assert "contact_damping" not in ev["supports"]
        assert ev["contact_damping_ratio"] < 0.05
