"""`evaluate` reports the restoring-force cross-check per recording and in the metrics."""

from __future__ import annotations

from pathlib import Path

import pytest

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.measurement.evaluate import evaluate_campaign

MANIFEST = Path(__file__).resolve().parents[1] / "examples" / "hidden_effect_manifest.csv"


@pytest.fixture(scope="module")
def damped(tmp_path_factory):
    """The hidden-effect manifest (8 recordings, beta 8-95) with a damped contact, zeta 0.3."""
    out = tmp_path_factory.mktemp("xcheck") / "damped"
    return load_campaign(
        simulate_campaign(MANIFEST, out, ["contact_damping:damping_ratio=0.3"], seed=0)
    )


def test_evaluate_reports_the_restoring_force_cross_check(damped):
    res = evaluate_campaign(damped)
    rf = res["metrics"]["restoring_force"]
    assert rf["n"] == 8
    # the physical estimate models the contact's dissipation (restitution ~0.4 at
    # zeta = 0.3): measured MAPE 0.11-0.15 (the hardest contacts, 8 samples each, are
    # under-estimated: see docs/crosscheck.md); a model trained on elastic contacts
    # alone gave 0.33 here, the shipped CNN trained on the randomised world 0.06
    assert rf["beta_mape"] < 0.25
    assert res["metrics"]["learned"]["beta_mape"] < 0.25
    assert rf["interval_coverage"] is not None and rf["agreement_with_learned"] is not None
    for r in res["recordings"]:
        assert {
            "restoring_force_class",
            "restoring_force_beta",
            "restoring_force_reason",
            "sensor",
        } <= set(r)
    assert "restoring_force" in next(iter(res["slices"]["beta_class"].values()))
