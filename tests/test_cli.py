"""The command line: subcommands, --json, exit code 2 with one line on bad input."""

import json
import os
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from stiffnet.cli import app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


def test_help_lists_commands():
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0
    for cmd in ("simulate", "simulate-campaign", "effects"):
        assert cmd in res.output


def test_command_help_paragraphs_fill_an_80_column_terminal():
    """A docstring's second paragraph kept its own line breaks, so at 80 columns 'read with
    its' / 'row (f_n, ...' / 'leave them' / 'empty' came out cut mid-phrase, with ``marks``."""
    env = {**os.environ, "COLUMNS": "80", "PYTHONPATH": os.pathsep.join(sys.path)}
    for command in ("predict", "predict-batch"):
        text = subprocess.run([sys.executable, "-m", "stiffnet", command, "--help"], env=env,
                              capture_output=True, text=True, check=True).stdout  # fmt: skip
        description = text.split("╭")[0].splitlines()[2:]  # after the usage line
        lines = [line.strip() for line in description]
        for line, following in zip(lines, lines[1:], strict=False):
            assert not (line and following and len(line) < 50), (command, line, following)
        assert "``" not in text and "natural_frequency_hz of the" in text  # --fn's default


def test_simulate_writes_dataset_and_json(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(
        "n_trajectories: 4\nshard_size: 4\nwindows: {duration_periods: 4, per_trajectory: 1}\n"
        "sweep: {fs_ratio: [50, 60]}\nsolver: {settle_tolerance: 0.2}\n"
    )
    res = runner.invoke(
        app, ["simulate", "--config", str(cfg), "--out", str(tmp_path / "ds"), "--json",
              str(tmp_path / "r.json")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    result = json.loads((tmp_path / "r.json").read_text())
    assert result["n_windows"] == 4 and (tmp_path / "ds" / "card.json").is_file()


def test_effects_json_lists_all_canonical(tmp_path):
    res = runner.invoke(app, ["effects", "--json", str(tmp_path / "e.json")])
    assert res.exit_code == 0, res.output
    names = {e["name"] for e in json.loads((tmp_path / "e.json").read_text())}
    assert {"contact_damping", "forcing_harmonics", "gap_drift", "sensor_dynamics", "adc"} <= names


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "stiffnet", *args], capture_output=True, text=True, cwd=ROOT,
        timeout=120,
    )  # fmt: skip


def test_bad_config_is_one_line_exit_2(tmp_path):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("sweep: {beta: [0, 500]}\n")
    res = run_cli("simulate", "--config", str(cfg), "--out", str(tmp_path / "o"))
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "sweep.beta" in lines[0] and "Traceback" not in res.stderr
    assert not (tmp_path / "o").exists()


def test_bad_effect_option_is_one_line_exit_2(tmp_path):
    res = run_cli("simulate-campaign", str(tmp_path / "m.csv"), "--out", str(tmp_path / "o"),
                  "--effect", "adc:bits=abc")  # fmt: skip
    assert res.returncode == 2
    assert "bits='abc' is not a number" in res.stderr and "Traceback" not in res.stderr


def test_simulate_campaign_cli_round_trip(tmp_path):
    manifest = tmp_path / "m.csv"
    manifest.write_text(
        "recording,fs_hz,frequency_ratio,amplitude,gap,damping_ratio,beta,duration_s\n"
        "r1.csv,500,1.05,1.9,2.8,0.02,20,2\n"
    )
    res = runner.invoke(
        app, ["simulate-campaign", str(manifest), "--out", str(tmp_path / "c"), "--effect",
              "contact_damping:damping_ratio=0.1", "--json", str(tmp_path / "r.json")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    card = json.loads((tmp_path / "c" / "campaign_card.json").read_text())
    assert "contact_damping" in json.dumps(card)
    lines = (tmp_path / "c" / "r1.csv").read_text().splitlines()
    assert lines[0] == "t,accel" and len(lines) == 1 + 2 * 500


def test_the_command_line_gives_openblas_one_thread_unless_the_user_chose():
    from stiffnet.cli.app import single_threaded_blas

    env: dict[str, str] = {}
    assert single_threaded_blas(env) and env == {"OPENBLAS_NUM_THREADS": "1"}
    chosen = {"OMP_NUM_THREADS": "2"}
    assert not single_threaded_blas(chosen) and chosen == {"OMP_NUM_THREADS": "2"}
    # the process a command runs in: numpy's and scipy's OpenBLAS report one thread
    script = (
        "from stiffnet.cli.app import single_threaded_blas; single_threaded_blas();"
        "import numpy, scipy.linalg, threadpoolctl;"
        "print(sorted({p['num_threads'] for p in threadpoolctl.threadpool_info()"
        " if p['user_api'] == 'blas'}))"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS",
           "GOTO_NUM_THREADS", "OMP_NUM_THREADS")}  # fmt: skip
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[1]"
