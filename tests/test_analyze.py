"""`stiffnet analyze`: the paper's pipeline on one recording, JSON keys, plots, bad input."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from stiffnet.analyze import analyze_signal
from stiffnet.cli import app
from stiffnet.recordings import write_recording_csv
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.simulator import Simulator

ROOT = Path(__file__).resolve().parents[1]
FN = 9.48
runner = CliRunner()

REQUIRED = (
    "embedding_delay", "embedding_dimension", "determinism_factor", "inclination_before_deg",
    "inclination_after_deg", "geometric_beta", "geometric_class",
)  # fmt: skip


def simulated(beta: float, gap: float = 2.8, n: int = 12000, noise: float = 0.01) -> np.ndarray:
    batch = OscillatorBatch.single(beta, gap, 1.9, 1.05, 0.02)
    res = Simulator(settle_tolerance=0.01).simulate(batch, 100.0, n, noise=noise, rng=3)
    return res.accel[0]


@pytest.fixture(scope="module")
def impact_csv(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("rec") / "beta31.csv"
    write_recording_csv(path, simulated(31.0) * 123.0, 100 * FN)  # arbitrary sensor gain
    return path


def test_analyze_json_keys_and_plots(impact_csv, tmp_path):
    res = runner.invoke(
        app, ["analyze", str(impact_csv), "--fn", str(FN), "--json", str(tmp_path / "a.json"),
              "--plots", str(tmp_path / "figs")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    result = json.loads((tmp_path / "a.json").read_text())
    for key in REQUIRED:
        assert key in result
    assert result["contact_detected"] is True and result["impacts_found"] > 20
    assert result["geometric_class"] in {"medium", "hard"}  # beta = 31, class edge at 35
    assert result["determinism_factor"] > 0.8  # Fig. 6: ~0.91 for an impacting case
    assert result["inclination_after_deg"] > result["inclination_before_deg"]
    # the restoring-force cross-check: gain-free beta from the force-displacement map
    assert result["restoring_force_class"] == "medium"
    assert result["restoring_force_beta"] == pytest.approx(31.0, rel=0.03)
    lo, hi = result["restoring_force_beta_interval"]
    assert lo <= result["restoring_force_beta"] <= hi
    assert result["restoring_force"]["ok"] and result["restoring_force"]["n_impacts"] > 20
    names = {Path(p).name for p in result["plots"]}
    assert names == {"ami.png", "dimension.png", "attractor_xz.png", "tangent_histogram.png",
                     "inclinations.png", "force_displacement.png"}  # fmt: skip
    for p in result["plots"]:
        assert Path(p).stat().st_size > 5000
    assert result["natural_frequency_source"] == "option --fn"
    assert result["stationarity_tested"].startswith("the whole record")


def test_analyze_without_natural_frequency_says_so(impact_csv, tmp_path):
    res = runner.invoke(app, ["analyze", str(impact_csv), "--json", str(tmp_path / "a.json")])
    assert res.exit_code == 0, res.output
    result = json.loads((tmp_path / "a.json").read_text())
    assert result["natural_frequency_hz"] is None and result["restoring_force_beta"] is None
    assert result["restoring_force"]["reason"].startswith("natural frequency unknown")
    assert result["geometric_class"] in {"medium", "hard"}  # the rest stands


def test_stationarity_reads_the_whole_record():
    """A change of beta after the first 20,000 samples makes the record non-stationary."""
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    from drill_records import layered_record

    x, _ = layered_record([10.0, 45.0], [15.0, 15.0], fs_hz=2000.0, noise=0.01, seed=2)
    a = analyze_signal(x, 2000.0)
    assert not a.stationary
    spans = a.summary()["stationarity_segments_s"]
    assert len(spans) == 8 and spans[0][0] < 2.0 and spans[-1][1] > 28.0
    assert "spread from" in a.stationarity_tested()
    c, _ = layered_record([10.0], [30.0], fs_hz=2000.0, noise=0.01, seed=2)
    assert analyze_signal(c, 2000.0).stationary


def test_no_impact_gives_no_contact_not_a_number():
    a = analyze_signal(simulated(31.0, gap=50.0), 100 * FN, FN).summary()
    assert a["contact_detected"] is False and a["impacts_found"] == 0
    assert a["geometric_class"] == "no_contact" and a["geometric_beta"] is None
    assert a["restoring_force_class"] == "no_contact" and a["restoring_force_beta"] is None
    assert a["restoring_force"]["reason"].startswith("no contact")


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "stiffnet", *args], capture_output=True, text=True, cwd=ROOT,
        timeout=120,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("signal", "needle"),
    [
        (np.ones(5000), "constant"),
        (np.r_[np.sin(np.arange(5000) / 10.0), np.nan], "NaN"),
        (np.sin(np.arange(20) / 3.0), "short"),
    ],
)
def test_bad_signals_one_line_exit_2(tmp_path, signal, needle):
    path = tmp_path / "x.npy"
    np.save(path, signal)
    res = run_cli("analyze", str(path), "--fs", "1000")
    assert res.returncode == 2, res.stderr
    assert needle.lower() in res.stderr.lower() and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_npy_needs_fs(tmp_path):
    path = tmp_path / "x.npy"
    np.save(path, np.sin(np.arange(5000) / 10.0))
    res = run_cli("analyze", str(path))
    assert res.returncode == 2 and "fs" in res.stderr.lower()


def test_a_restoring_force_beta_not_read_says_why_in_the_table(tmp_path):
    """The table showed 'restoring_force_beta None' with the reason in the JSON only (a
    restraint with its own mass: 'the contact law explains 2% of the contact force')."""
    t = np.arange(5000) / 1000
    x = np.sin(2 * np.pi * 9.95 * t) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    path = write_recording_csv(tmp_path / "free.csv", x, 1000.0)
    res = CliRunner().invoke(app, ["--wide", "analyze", str(path), "--fn", "9.48"])
    assert res.exit_code == 0, res.output
    line = next(ln for ln in res.output.splitlines() if "restoring_force_reason" in ln)
    assert "no contact: 0 excursion(s)" in line
