"""``report`` on a field campaign (no beta): the three readings of beta side by side."""

from __future__ import annotations

import csv
import json

import pytest
from typer.testing import CliRunner

from stiffnet.campaign import simulate_campaign
from stiffnet.cli import app
from stiffnet.measurement.report import field_section, is_field_campaign, why_betas_differ

PLAN = (
    "recording,fs_hz,natural_frequency_hz,frequency_ratio,amplitude,gap,damping_ratio,beta,"
    "duration_s,noise\n"
    "a.csv,1000,9.48,1.05,1.9,2.8,0.02,12,6,0.02\n"
    "b.csv,1000,9.48,1.0,1.2,1.2,0.02,45,6,0.02\n"
    "c.csv,1000,9.48,0.95,1.0,0.5,0.02,25,6,0.02\n"
)


@pytest.fixture(scope="module")
def field(tmp_path_factory):
    """A campaign whose manifest tells no beta (and no gap): what a field user has."""
    root = tmp_path_factory.mktemp("field")
    (root / "plan.csv").write_text(PLAN)
    camp = simulate_campaign(root / "plan.csv", root / "camp", ["contact_damping"], seed=4)
    rows = list(csv.DictReader((camp / "manifest.csv").open()))
    keep = ["recording", "fs_hz", "natural_frequency_hz", "frequency_ratio", "amplitude",
            "damping_ratio"]  # fmt: skip
    with (camp / "manifest.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, keep)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in keep})
    return camp


def _row(**kw):
    base = {"recording": "r.csv", "beta": None, "class": "hard", "beta_estimate": 45.0,
            "beta_interval": [40.0, 50.0], "restoring_force_beta": 44.0,
            "restoring_force_beta_interval": [42.0, 46.0], "ood_checks": [],
            "restoring_force_reason": "ok"}  # fmt: skip
    return {**base, **kw}


def test_reasons_name_what_differs():
    assert why_betas_differ(_row(), 46.0, ["gap", "beta"]).startswith("the readings agree")
    text = why_betas_differ(_row(), 70.0, ["gap", "beta"])
    assert "nuisance of the simulator" in text and "jointly with gap" in text
    text = why_betas_differ(
        _row(restoring_force_beta=20.0, restoring_force_beta_interval=[18, 22]), 46.0, []
    )
    assert "restoring force reads the contact law itself" in text
    text = why_betas_differ(
        _row(restoring_force_beta=None, restoring_force_reason="no contact"), None, []
    )
    assert "no restoring-force beta: no contact" in text
    assert "blend of layers" in why_betas_differ(_row(ood_checks=["layers"]), None, [])


def test_field_section_puts_the_readings_side_by_side():
    ev = {"model": {"name": "cnn"}, "recordings": [_row(), _row(recording="s.csv", ood=True,
          ood_checks=["embedding"], restoring_force_agreement=True, agreement=True)]}  # fmt: skip
    assert is_field_campaign(ev)
    page = "".join(field_section(ev, {"nuisances": {"beta": [46.0, 80.0], "gap": [1, 2]}}))
    assert "beta (diagnose fit)" in page and "80" in page and "jointly with gap" in page
    assert "Alarm on 1 of 2" in page
    assert "No diagnose result" in "".join(field_section(ev, None))


@pytest.mark.slow
def test_report_renders_a_field_campaign(field, tmp_path):
    out = tmp_path / "r.html"
    res = CliRunner().invoke(app, ["report", str(field), "--out", str(out), "--no-diagnose",
                                   "--json", str(tmp_path / "r.json")])  # fmt: skip
    assert res.exit_code == 0, res.output
    page = out.read_text()
    assert "Field campaign: no beta is known" in page
    assert "beta (restoring force)" in page and "why they differ" in page
    assert "Compare: simulator versus measurement" in page
    assert json.loads((tmp_path / "r.json").read_text())["discrepancy"] > 0
