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


def test_the_chain_is_fitted_on_a_few_recordings_spread_over_the_campaign():
    from stiffnet.measurement.evidence import _as_sheet, _spread

    assert _spread(list(range(24)), 3) == [0, 12, 23]
    assert _spread([1, 4, 6, 9], 3) == [1, 6, 9]
    assert _spread([2, 5], 3) == [2, 5]
    # a shared chain becomes a data sheet with a whole low-pass order; no stage to undo: none
    shared = {"n": 3, "resonance_hz": 237.0, "resonance_damping": 0.03, "lowpass_hz": 150.0,
              "lowpass_order": 1.5, "highpass_hz": None}  # fmt: skip
    sheet = {"resonance_hz": 237.0, "resonance_damping": 0.03, "lowpass_hz": 150.0,
             "lowpass_order": 2.0, "highpass_hz": 0.0}  # fmt: skip
    assert _as_sheet(shared) == sheet
    assert _as_sheet({"n": 3, "resonance_hz": None, "lowpass_hz": None, "highpass_hz": 1.0}) is None
    assert _as_sheet(None) is None


@pytest.mark.slow
def test_one_accelerometer_chain_fitted_on_three_recordings_is_undone_on_the_rest(tmp_path):
    """5 recordings through a 237 Hz accelerometer resonance and a damped contact: the chain
    is fitted on 3 of them, the other 2 are read through the chain those share, and the
    evidence says so; the contact damping and the chain are still read."""
    from campaign_helpers import short_manifest

    from stiffnet.measurement.evidence import contact_law_per_recording

    hidden = ["contact_damping:damping_ratio=0.25",
              "sensor_dynamics:resonance_hz=237,resonance_damping=0.03,lowpass_hz=0"]  # fmt: skip
    camp = load_campaign(simulate_campaign(short_manifest(tmp_path, 5, "2"), tmp_path / "c",
                                           hidden, seed=0))  # fmt: skip
    per = contact_law_per_recording(camp, camp.rows)
    shared = [p for p in per if p.get("chain_shared")]
    names = [r.recording for r in camp.rows]
    assert [p["recording"] for p in shared] == [names[1], names[3]]
    assert all(p["chain_fitted_on"] == [names[0], names[2], names[4]] for p in shared)
    assert all(p["sensor"]["source"] == "data sheet" for p in shared)
    assert all(p["sensor"]["source"] == "fitted" for p in per if not p.get("chain_shared"))
    assert shared[0]["sensor"]["resonance_hz"] == pytest.approx(237.0, rel=0.01)
    ev = contact_evidence(per)
    assert ev["sensor"]["n"] == 3  # the fitted chains only, not the copies undone
    assert ev["sensor"]["resonance_hz"] == pytest.approx(237.0, rel=0.01)
    assert ev["chain_fitted_on"] == [names[0], names[2], names[4]]
    assert (
        "fitted on 3 of them" in ev["summary"]
        and "undone as shared on the other 2" in ev["summary"]
    )
    assert ev["supports"] == ["contact_damping"] and ev["answered"] >= 4
    assert ev["contact_damping_ratio"] == pytest.approx(0.25, abs=0.08)
