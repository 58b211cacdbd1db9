"""Bounded parsing: every hostile input is one line (exit 2, or 1 for the environment), fast.

Each case is a red-team finding: oversized CSV cells, a YAML alias bomb, unusable
tracking URIs, a full disk, out-of-range seeds, effect values, odd names.
"""

from __future__ import annotations

import errno
import shutil
import time

import numpy as np
import pytest
from test_contract import CAMPAIGN, EXAMPLE, ROOT, one_line_error, runner

from stiffnet.cli import app
from stiffnet.errors import StiffnetError

MODEL = ROOT / "models" / "gbm.onnx"
MANIFEST = ROOT / "examples" / "campaign_manifest.csv"


def test_csv_cell_over_the_field_limit_is_one_line(tmp_path):
    for name, text, said in [
        ("cell.csv", "t,accel\n0," + "1" * 200_000 + "\n1,2\n", "malformed CSV"),
        ("head.csv", "t" + "x" * 200_000 + ",accel\n0,1\n", "line 1 is longer than 65536"),
    ]:
        p = tmp_path / name
        p.write_text(text)
        one_line_error(["predict", p, "--model", MODEL], said)


def test_csv_cell_over_the_field_limit_is_422_over_http():
    from fastapi.testclient import TestClient

    from serving.app import create_app
    from serving.predictor import Predictor

    big = ("t,accel\n0," + "1" * 200_000 + "\n1,2\n").encode()
    with TestClient(create_app(Predictor.load(MODEL))) as c:
        r = c.post("/predict", files={"file": ("x.csv", big)})
    assert r.status_code == 422 and "CSV" in r.json()["error"], r.text


def test_yaml_alias_bomb_is_refused_at_once(tmp_path):
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        prev, cur = chr(96 + i), chr(97 + i)
        lines.append(f"{cur}: &{cur} [" + ",".join([f"*{prev}"] * 9) + "]")
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("\n".join(lines) + "\n")
    assert len(bomb.read_bytes()) < 500
    t = time.monotonic()
    one_line_error(["simulate", "--config", bomb, "--out", tmp_path / "o"], "aliases")
    one_line_error(["train", "--data", tmp_path, "--config", bomb], "aliases")
    assert time.monotonic() - t < 5 and not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("uri", "needle"),
    [("garbage://x", "unsupported scheme"), ("sqlite:////nonexistent-ro/m.db", "does not exist"),
     ("file:///etc/passwd", "not a folder"), ("sqlite:///", "name a database file")],
)  # fmt: skip
def test_tracking_uri_is_checked_before_training(tmp_path, uri, needle):
    one_line_error(["train", "--data", tmp_path / "d", "--out", tmp_path / "m", "--tracking-uri",
                    uri], needle)  # fmt: skip
    assert not (tmp_path / "m").exists()


def test_unreachable_tracking_server_is_exit_1_within_seconds(tmp_path):
    from live_server import free_port

    port = free_port()  # nobody listens there
    t = time.monotonic()
    res = runner.invoke(app, ["loop", str(CAMPAIGN), "--state", str(tmp_path / "s"),
                              "--tracking-uri", f"http://127.0.0.1:{port}"])  # fmt: skip
    assert res.exit_code == 1, res.output
    assert "not reachable" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert time.monotonic() - t < 10 and not (tmp_path / "s").exists()


def test_disk_full_is_one_line_exit_1_and_keeps_the_old_file(tmp_path, monkeypatch):
    import stiffnet.io_utils as io_utils

    rec = tmp_path / "rec.csv"
    shutil.copy(EXAMPLE, rec)
    out = tmp_path / "a.json"
    out.write_text("the previous result")

    def full(_fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(io_utils.os, "fsync", full)
    res = runner.invoke(
        app, ["predict", str(rec), "--model", str(MODEL), "--fn", "9.48", "--json", str(out)]
    )
    assert res.exit_code == 1, res.output
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith("error: ") and "No space left on device" in line
    assert out.read_text() == "the previous result"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "rec.csv"]  # no temporary


def test_seeds_states_and_effect_values_are_checked_first(tmp_path):
    one_line_error(["diagnose", CAMPAIGN, "--seed", "-1"], "--seed must be 0..")
    one_line_error(["compare", CAMPAIGN, "--seed", str(2**40)], "--seed must be 0..")
    state = tmp_path / "state.txt"
    state.write_text("mine")
    one_line_error(["loop", CAMPAIGN, "--state", state, "--no-tracking"], "not a folder")
    assert state.read_text() == "mine"
    t = time.monotonic()
    one_line_error(["loop", CAMPAIGN, "--add-effect", "contact_damping:damping_ratio=nan",
                    "--state", tmp_path / "l", "--no-tracking"], "not a finite number")  # fmt: skip
    one_line_error(
        [
            "loop",
            CAMPAIGN,
            "--add-effect",
            "contact_damping:damping_ratio=7",
            "--state",
            tmp_path / "l",
            "--no-tracking",
        ],
        "outside the allowed range",
    )
    one_line_error(["diagnose", CAMPAIGN, "--only", "no_such_effect"], "unknown effect")
    assert time.monotonic() - t < 10 and not (tmp_path / "l").exists()


def test_output_folders_that_cannot_be_written(tmp_path):
    one_line_error(["simulate", "--out", "/proc/x"], "cannot write in /proc")
    one_line_error(["simulate", "--out", tmp_path / ("x" * 300)], "longer than 255 bytes")
    one_line_error(["analyze", EXAMPLE, "--json", str(tmp_path) + "/a\x00b.json"], "--json")


@pytest.mark.parametrize(
    ("rows", "needle"),
    [(["a.csv", "a.csv/b.csv"], "both a file and a folder"),
     (["d/b.csv", "d"], "both a file and a folder"),
     (["x" * 300 + ".csv"], "usable file name"), (["a\x00b.csv"], "usable file name")],
)  # fmt: skip
def test_manifest_names_that_no_file_system_takes(tmp_path, rows, needle):
    head = "recording,fs_hz,frequency_ratio,amplitude,gap,damping_ratio,beta,duration_s\n"
    body = "".join(f"{r},500,1.05,1.9,2.8,0.02,12,0.2\n" for r in rows)
    (tmp_path / "m.csv").write_text(head + body)
    one_line_error(["simulate-campaign", tmp_path / "m.csv", "--out", tmp_path / "o"], needle)
    camp = tmp_path / "camp"
    camp.mkdir()
    (camp / "manifest.csv").write_text(head + body)
    one_line_error(["evaluate", camp, "--model", MODEL], needle)
    assert not (tmp_path / "o").exists()


def test_analyze_refuses_unphysical_rates_and_scales_tiny_signals(tmp_path):
    from stiffnet.analyze import analyze_signal
    from stiffnet.recordings import read_recording

    fast = tmp_path / "fast.csv"
    rec = read_recording(EXAMPLE)
    t = np.arange(rec.accel.size) * 1e-12
    rows = "".join(f"{a:.17g},{b:.17g}\n" for a, b in zip(t, rec.accel, strict=True))
    fast.write_text("t,accel\n" + rows)
    one_line_error(["analyze", fast], "sampling rate must be in")
    x = rec.accel[:4000]
    tiny = analyze_signal(x * 1e-30, rec.fs_hz).summary()  # was "signal is constant"
    assert tiny["geometric_class"] == analyze_signal(x, rec.fs_hz).summary()["geometric_class"]


@pytest.mark.parametrize(
    "change",
    [{"noise_floor": "x"}, {"restoring_force": [1, 2]}, {"restoring_force_evidence": [1, 2]},
     {"restoring_force": {"summary": 5}}, {"missing_effects": [1]},
     {"ranking": [{"effect": "x", "params": {}, "significant": True, "relative_reduction": 0.1,
                   "discrepancy_reduction": 0.1, "reasons": 5}]}],
)  # fmt: skip
def test_report_diagnosis_with_wrong_types_is_one_line(tmp_path, change):
    import json

    d = {"baseline_discrepancy": 1.0, "ranking": [], "missing_effect": None, **change}
    (tmp_path / "d.json").write_text(json.dumps(d))
    one_line_error(["report", CAMPAIGN, "--diagnosis", tmp_path / "d.json", "--out",
                    tmp_path / "r.html"], "d.json")  # fmt: skip
    assert not (tmp_path / "r.html").exists()


def test_matplotlib_names_are_plain_text(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from stiffnet.inputs import mpl_text
    from stiffnet.measurement import plots

    fig = plots.ranking_figure(
        {"baseline_discrepancy": 1.0, "ranking": [{"effect": "law$^}$", "params": {},
         "significant": True, "relative_reduction": 0.2, "discrepancy_reduction": 0.2}]},
        tmp_path / "r.png",
    )  # fmt: skip
    assert fig.is_file() and fig.stat().st_size > 1000
    assert mpl_text("r$^}$.csv") == r"r\$^}\$.csv"


def test_globs_are_bounded_and_never_follow_folder_links(tmp_path):
    from stiffnet.inputs import walk_files

    (tmp_path / "a").mkdir()
    for i in range(60):
        (tmp_path / "a" / f"r{i}.csv").write_text("t,accel\n")
    (tmp_path / "a" / "loop").symlink_to(tmp_path / "a")  # a link cycle
    assert len(walk_files(str(tmp_path / "**" / "*.csv"))) == 60
    with pytest.raises(StiffnetError, match="more than 50 entries"):
        walk_files(str(tmp_path / "**" / "*.csv"), limit=50)
    assert [p.name for p in walk_files(str(tmp_path / "a" / "r1?.csv"))] != []


def test_deep_documents_anywhere_are_one_line(tmp_path, monkeypatch):
    """A RecursionError from any reader (ONNX metadata, a card's JSON) is one line, exit 2."""
    import serving.predictor as predictor_module

    def deep(*_a, **_k):
        raise RecursionError("maximum recursion depth exceeded while decoding a JSON object")

    monkeypatch.setattr(predictor_module.Predictor, "load", deep)
    rec = tmp_path / "rec.csv"
    shutil.copy(EXAMPLE, rec)
    one_line_error(["predict", rec], "nested too deeply")
