"""One simulation of a campaign for the discrepancy and the impact regime.

The loop's evaluation reads each recording's impact regime from the contact facts of the
discrepancy's simulation (``compare_campaign(..., contact=True)``) instead of simulating
the campaign a second time (``simulated_contact``): the discrepancy must not move, and the
regimes must be those of the evaluation's own simulation.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.campaign.loaded import LoadedCampaign
from stiffnet.campaign.simulate import impact_regime, simulated_contact
from stiffnet.effects.contact_damping import ContactDamping
from stiffnet.measurement import evaluate as evaluate_mod
from stiffnet.measurement.compare import compare_campaign
from stiffnet.measurement.evaluate import evaluate_campaign

GBM = Path(__file__).resolve().parents[1] / "models" / "gbm.onnx"
#: An impacting row, one whose motion stays short of a far stop, one hitting a stiff stop.
ROWS = [
    {"recording": "hit.csv", "beta": 20, "gap": 0.8, "amplitude": 1.2, "frequency_ratio": 1.02},
    {"recording": "free.csv", "beta": 30, "gap": 3.0, "amplitude": 0.3, "frequency_ratio": 0.9},
    {"recording": "stiff.csv", "beta": 70, "gap": 1.6, "amplitude": 1.5, "frequency_ratio": 0.98},
]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("facts")
    manifest = tmp / "manifest.csv"
    with open(manifest, "w", encoding="utf-8", newline="") as fh:
        cols = [*ROWS[0], "fs_hz", "damping_ratio", "duration_s", "noise"]
        w = csv.DictWriter(fh, fieldnames=cols)
        w.writeheader()
        for r in ROWS:
            w.writerow({**r, "fs_hz": 1000, "damping_ratio": 0.02, "duration_s": 3, "noise": 0.02})
    return load_campaign(simulate_campaign(manifest, tmp / "c", [], seed=0))


@pytest.mark.parametrize("effects", [[], [ContactDamping(damping_ratio=0.2)]])
def test_the_discrepancys_simulation_gives_the_impact_regime(campaign, effects):
    plain = compare_campaign(LoadedCampaign.of(campaign), effects)
    shared = compare_campaign(LoadedCampaign.of(campaign), effects, contact=True)
    # the same simulation: the discrepancy to the bit
    assert json.dumps(shared.result) == json.dumps(plain.result)
    assert plain.contact is None
    own = simulated_contact(campaign.rows, effects)
    regimes = [impact_regime(c) for c in shared.contact]
    assert regimes == [impact_regime(c) for c in own] == ["impacting", "no_contact", "impacting"]
    # another length and transient, the same motion: its contact facts agree closely (short
    # of the stop, how far short moves with what is left of the transient's beat)
    for a, b in zip(own, shared.contact, strict=True):
        assert b["contact_fraction"] == pytest.approx(a["contact_fraction"], abs=0.02)
        assert b["impacts_per_period"] == pytest.approx(a["impacts_per_period"], abs=0.1)
        if a["contact_fraction"] > 0:
            assert b["max_penetration_ratio"] == pytest.approx(a["max_penetration_ratio"], abs=0.05)


def test_evaluate_takes_the_given_contact_facts(campaign, monkeypatch):
    shared = compare_campaign(LoadedCampaign.of(campaign), [], contact=True)
    own = evaluate_campaign(LoadedCampaign.of(campaign), str(GBM), [], require_beta=False)

    def refused(*args, **kwargs):
        raise AssertionError("the campaign was simulated again")

    monkeypatch.setattr(evaluate_mod, "simulated_contact", refused)
    given = evaluate_campaign(
        LoadedCampaign.of(campaign), str(GBM), [], require_beta=False, contact=shared.contact
    )
    assert [r["impact_regime"] for r in given["recordings"]] == ["impacting", "no_contact",
                                                                 "impacting"]  # fmt: skip
    # everything equal but the reading by simulation's own CPU seconds
    for evaluation in (given, own):
        evaluation["simulation"].pop("cpu_seconds")
    assert json.dumps(given) == json.dumps(own)


def test_report_simulates_the_campaign_once(campaign, tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from stiffnet.cli import app

    def refused(*args, **kwargs):
        raise AssertionError("the campaign was simulated again")

    monkeypatch.setattr(evaluate_mod, "simulated_contact", refused)
    html, out = tmp_path / "r.html", tmp_path / "r.json"
    args = ["report", campaign.folder, "--model", GBM, "--no-diagnose", "--out", html,
            "--json", out]  # fmt: skip
    res = CliRunner().invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    assert html.is_file()
    assert json.loads(out.read_text())["discrepancy"] > 0
