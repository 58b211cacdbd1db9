"""The measurement commands end to end: evaluate, compare, diagnose, report (and bad input)."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from stiffnet.campaign import ManifestRow, simulate_campaign, write_manifest
from stiffnet.cli import app

runner = CliRunner()


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cli")
    rows = [
        ManifestRow(
            recording=f"r{b:03d}.csv",
            fs_hz=fs,
            natural_frequency_hz=9.48,
            frequency_ratio=w,
            amplitude=a,
            gap=e,
            damping_ratio=0.02,
            beta=b,
            duration_s=2.5,
            noise=0.02,
        )
        for b, fs, w, a, e in (
            (10, 1000, 1.05, 1.9, 2.8),
            (25, 1250, 1.1, 1.9, 2.0),
            (45, 1500, 1.08, 1.7, 2.4),
            (80, 2000, 1.05, 1.9, 2.8),
        )
    ]
    write_manifest(tmp / "plan.csv", rows)
    return simulate_campaign(tmp / "plan.csv", tmp / "camp", ["contact_damping:damping_ratio=0.3"])


def _run(args):
    res = runner.invoke(app, [str(a) for a in args])
    return res


def test_evaluate_json_contract(campaign, tmp_path):
    out = tmp_path / "ev.json"
    res = _run(["evaluate", campaign, "--json", out])
    assert res.exit_code == 0, res.output
    ev = json.loads(out.read_text())
    for r in ev["recordings"]:
        assert {
            "recording",
            "beta",
            "class",
            "beta_estimate",
            "geometric_class",
            "geometric_beta",
            "impact_regime",
        } <= set(r)
        assert r["impact_regime"] == "impacting"
    for method in ("learned", "geometric"):
        assert {"accuracy", "beta_mape", "macro_f1"} <= set(ev["metrics"][method])
    assert set(ev["slices"]) == {
        "beta_class",
        "impact_regime",
        "gap",
        "frequency_ratio",
        "amplitude",
    }
    assert ev["worst"]


def test_evaluate_names_the_recordings_it_leaves_unscored(campaign, tmp_path):
    """A calibration sheet with one beta left blank: the metrics count the others, and the
    output says which recording is predicted but not scored (was: n 3 of 4, unexplained)."""
    import shutil

    folder = shutil.copytree(campaign, tmp_path / "camp")
    manifest = folder / "manifest.csv"
    lines = manifest.read_text().splitlines()
    cols = lines[0].split(",")
    i = cols.index("beta")
    cells = lines[2].split(",")
    blank = cells[0]
    cells[i] = ""
    lines[2] = ",".join(cells)
    manifest.write_text("\n".join(lines) + "\n")
    out = tmp_path / "ev.json"
    res = _run(["--wide", "evaluate", folder, "--json", out])
    assert res.exit_code == 0, res.output
    ev = json.loads(out.read_text())
    assert ev["metrics"]["learned"]["n"] == len(ev["recordings"]) - 1
    assert f"not scored: 1 of {len(ev['recordings'])} recordings have no beta" in res.output
    assert f"({blank}): predicted, left out of the metrics" in res.output


def test_compare_writes_plots(campaign, tmp_path):
    out = tmp_path / "cmp.json"
    res = _run(["compare", campaign, "--plots", tmp_path / "figs", "--json", out])
    assert res.exit_code == 0, res.output
    cmp = json.loads(out.read_text())
    assert cmp["discrepancy"] > 1.0  # the damped contact is missing from the default config
    assert cmp["failure"]["component"] in cmp["by_component"]
    assert len(cmp["plots"]) == 3
    for p in cmp["plots"]:
        assert (tmp_path / "figs" / p.split("/")[-1]).stat().st_size > 5000


def test_diagnose_and_report(campaign, tmp_path):
    dj = tmp_path / "diag.json"
    res = _run(
        [
            "diagnose",
            campaign,
            "--only",
            "contact_damping",
            "--only",
            "adc",
            "--budget",
            "8",
            "--no-inclination",
            "--json",
            dj,
        ]
    )
    assert res.exit_code == 0, res.output
    diag = json.loads(dj.read_text())
    assert diag["missing_effect"] == "contact_damping"
    assert [r["effect"] for r in diag["ranking"]][0] == "contact_damping"
    assert diag["verdict"] in ("explained", "partially_explained")
    assert "verdict:" in res.output and "why not" in res.output
    assert all(r["reasons"] for r in diag["ranking"] if not r["selected"])
    html = tmp_path / "report.html"
    res = _run(["report", campaign, "--diagnosis", dj, "--out", html])
    assert res.exit_code == 0, res.output
    page = html.read_text()
    assert page.count("data:image/png;base64,") >= 4 and "<style>" in page
    assert "contact_damping" in page and 'src="http' not in page
    assert "Verdict" in page and "why not" in page
    # each recording against its own floor, with its orbit: terminal, JSON and report
    assert [r["recording"] for r in diag["per_recording"]] == diag["recordings"]
    assert "Per recording" in page and "measured orbit" in page


@pytest.mark.parametrize(
    "args",
    [
        ["compare", "no/such/campaign"],
        ["diagnose", "{camp}", "--only", "no_such_effect"],
        ["loop", "{camp}", "--add-effect", "contact_damping", "--model", "svm"],
    ],
)
def test_bad_input_is_one_line_exit_2(campaign, args):
    res = _run([a.format(camp=campaign) for a in args])
    assert res.exit_code == 2, res.output
    assert "error:" in res.output and "Traceback" not in res.output
