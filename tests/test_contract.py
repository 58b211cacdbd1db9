"""The contract at every boundary (issue 15): bad input is one line, exit 2 (HTTP 4xx JSON),
never a traceback nor a silently wrong output; outputs never destroy what is not theirs.

Each explicit case is one of the red-team findings; the hypothesis tests probe the
parsers with generated input.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from stiffnet.cli import app
from stiffnet.errors import StiffnetError

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "recordings" / "impact_beta12.csv"
CAMPAIGN = ROOT / "examples" / "hidden_effect_campaign"
runner = CliRunner()


def one_line_error(args: list[str], *needles: str) -> str:
    """Run the CLI in-process: exit 2, exactly one stderr line, naming ``needles``."""
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 2, (res.exit_code, res.output, res.exception)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("error: ") and "Traceback" not in res.output
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


@pytest.fixture
def recording(tmp_path):
    """A copy of the example recording (without its sidecar)."""
    p = tmp_path / "r.csv"
    shutil.copy(EXAMPLE, p)
    return p


# ------------------------------------------------------------- the one-line contract (CLI)


def test_typer_usage_errors_are_one_line(recording):
    one_line_error(["analyze", recording, "--fs", "abc"], "--fs")
    one_line_error(["analyze"], "Missing argument")
    one_line_error(["no-such-command"], "no-such-command")


def test_recording_name_with_newline_or_markup_is_one_line(tmp_path):
    line = one_line_error(["analyze", tmp_path / "a\nb.txt"], "a\\nb.txt")
    assert "unknown recording extension" in line
    one_line_error(["analyze", tmp_path / "[red]x.txt"], "[red]x.txt")  # not rich markup


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ('{"natural_frequency_hz": 1' + "0" * 400 + "}", "too large"),
        ("[" * 100_000 + "]" * 100_000, "nested deeper"),
        ('{"natural_frequency_hz": Infinity}', "not valid JSON"),
        ('{"natural_frequency_hz": 1e400}', "too large"),
        ('{"natural_frequency_hz": true}', "must be a number"),  # was read as f_n = 1 Hz
        ('{"natural_frequency_hz": "9.48"}', "must be a number"),
        ('{"natural_frequency_hz": 1e-30}', "natural_frequency_hz must be in"),
        (b"\xff\xfe{}", "not UTF-8"),
    ],
)
def test_bad_sidecars_are_one_line(recording, content, needle):
    side = Path(str(recording) + ".json")
    side.write_bytes(content if isinstance(content, bytes) else content.encode())
    one_line_error(["predict", recording], needle)


def test_deep_model_card_is_one_line(tmp_path, recording):
    for name in ("gbm.onnx", "ood_reference.json"):
        shutil.copy(ROOT / "models" / name, tmp_path / name)
    (tmp_path / "gbm.card.json").write_text("[" * 100_000 + "]" * 100_000)
    one_line_error(["predict", recording, "--model", tmp_path / "gbm.onnx"], "model card")


def test_output_paths_are_checked_before_the_work(tmp_path, recording):
    res_line = one_line_error(["analyze", recording, "--json", "/nonexistent-dir/x.json"])
    assert "does not exist" in res_line
    res = runner.invoke(app, ["analyze", str(recording), "--json", str(tmp_path)])
    assert res.exit_code == 2 and res.stdout == ""  # refused before the result was printed
    one_line_error(["analyze", recording, "--json", "/proc/version"], "cannot write in /proc")
    one_line_error(["analyze", recording, "--json", "/dev/null"], "not a regular file")
    plots = tmp_path / "plots.txt"
    plots.write_text("mine")
    one_line_error(["analyze", recording, "--plots", plots], "not a folder")
    one_line_error(["report", CAMPAIGN, "--out", "/nonexistent-dir/r.html"], "does not exist")


def test_threads_are_bounded_by_the_cores(recording):
    one_line_error(["predict", recording, "--threads", "1099511627776"], "--threads")
    one_line_error(["predict", recording, "--threads", "100000"], "--threads")
    one_line_error(["predict", recording, "--threads", "0"], "--threads")


@pytest.mark.parametrize(
    ("text", "needle"),
    [(b"- a\n- b\n", "not a list"), (b"just a string\n", "not a string"),
     (b"\xff\xfe\x00seed: 1", "not UTF-8"), (b"a: [" * 3 + b"\n", "invalid YAML")],
)  # fmt: skip
def test_simulate_config_not_a_mapping(tmp_path, text, needle):
    cfg = tmp_path / "c.yaml"
    cfg.write_bytes(text)
    one_line_error(["simulate", "--config", cfg, "--out", tmp_path / "o"], needle)
    assert not (tmp_path / "o").exists()


def test_measurement_knobs_are_checked_first(tmp_path):
    one_line_error(["diagnose", CAMPAIGN, "--scheduler", "notaurl"], "scheduler")
    one_line_error(["diagnose", CAMPAIGN, "--budget", "-5"], "--budget must be")
    one_line_error(["diagnose", CAMPAIGN, "--budget-numerical", "0"], "--budget-numerical")
    for n in ("8", "0"):
        args = ["loop", CAMPAIGN, "--add-effect", "hertz_contact", "--n-trajectories", n]
        one_line_error([*args, "--out", tmp_path / "loop", "--no-tracking"], "--n-trajectories")
    assert not (tmp_path / "loop").exists()
    empty = tmp_path / "d.json"
    empty.write_text("{}")
    one_line_error(["report", CAMPAIGN, "--diagnosis", empty, "--out", tmp_path / "r.html"],
                   "not a `diagnose --json` result")  # fmt: skip
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    one_line_error(["report", CAMPAIGN, "--diagnosis", deep], "nested deeper")


# ------------------------------------------------------------------ silently wrong output


def test_tiny_rates_are_refused_not_written_as_infinity(recording, tmp_path):
    out = tmp_path / "p.json"
    one_line_error(["predict", recording, "--fs", "1e-306", "--fn", "1e-308", "--json", out],
                   "--fs must be in")  # fmt: skip
    assert not out.exists()


def test_json_outputs_are_strict_json(tmp_path):
    from stiffnet.io_utils import write_json_atomic

    out = tmp_path / "x.json"
    write_json_atomic(out, {"a": math.inf, "b": [np.nan, np.float32(2.0)], "c": np.array([1.0])})
    assert json.loads(out.read_text(), parse_constant=_refuse) == {"a": None, "b": [None, 2.0],
                                                                   "c": [1.0]}  # fmt: skip


def _refuse(name):
    raise AssertionError(f"{name} written into JSON")


def test_analysis_near_float_max_is_not_fake_nan():
    """The analysis is scale-free: the example times 2**1000 (~1e301) gives the same numbers."""
    from stiffnet.analyze import analyze_signal
    from stiffnet.recordings import read_recording

    rec = read_recording(EXAMPLE)
    x = rec.accel[:4000]
    plain = analyze_signal(x, rec.fs_hz).summary()
    huge = analyze_signal(np.ldexp(x / np.abs(x).max(), 1020), rec.fs_hz).summary()
    assert huge == analyze_signal(x / np.abs(x).max(), rec.fs_hz).summary()
    assert huge["geometric_class"] == plain["geometric_class"]


def test_evaluate_without_beta_is_refused(tmp_path):
    camp = tmp_path / "camp"
    camp.mkdir()
    shutil.copy(EXAMPLE, camp / "r1.csv")
    (camp / "manifest.csv").write_text("recording,fs_hz,natural_frequency_hz\nr1.csv,1000,9.48\n")
    one_line_error(["evaluate", camp], "no recording has a known beta")


# --------------------------------------------------------------------------- the HTTP side


@pytest.fixture(scope="module")
def client():
    from fastapi.testclient import TestClient

    from serving.app import create_app
    from serving.predictor import Predictor

    with TestClient(create_app(Predictor.load(ROOT / "models" / "gbm.onnx"))) as c:
        yield c


@pytest.mark.parametrize(
    "body",
    [
        {"samples": [True, False] * 600, "fs_hz": 1000},
        {"samples": [0.0, 1.0] * 600, "fs_hz": "1000"},
        {"samples": [0.0, 1.0] * 600, "fs_hz": True},
        {"samples": [0.0, 1.0] * 600, "fs_hz": 1e-306, "natural_frequency_hz": 1e-308},  # was 500
        {"samples": [0.0, 1.0] * 600, "fs_hz": 1000, "natural_frequency_hz": True},
    ],
)
def test_http_numbers_are_numbers(client, body):
    r = client.post("/predict", json=body)
    assert r.status_code == 422, r.text
    assert list(r.json()) == ["error"] and "\n" not in r.json()["error"]


# ------------------------------------------------------------------------ generated input

FIXTURE = HealthCheck.function_scoped_fixture
JSON_TEXT = st.one_of(
    st.text(max_size=60),
    st.recursive(
        st.none() | st.booleans() | st.floats(allow_nan=True) | st.integers() | st.text(max_size=5),
        lambda kids: (
            st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=4), kids, max_size=4)
        ),  # fmt: skip
        max_leaves=20,
    ).map(lambda v: json.dumps(v)),
)


@settings(max_examples=200, deadline=None)
@given(text=JSON_TEXT)
def test_parse_json_gives_finite_json_or_one_line_error(text):
    from stiffnet.inputs import parse_json

    try:
        obj = parse_json(text.encode(), "doc")
    except StiffnetError as exc:
        assert "\n" not in str(exc)
        return
    assert json.loads(json.dumps(obj, allow_nan=False)) == obj  # finite, plain JSON


@settings(max_examples=200, deadline=None)
@given(value=st.one_of(st.booleans(), st.text(max_size=8), st.none(), st.floats(),
                       st.integers(min_value=-(10**400), max_value=10**400)))  # fmt: skip
def test_sampling_rate_accepts_only_physical_numbers(value):
    from stiffnet.inputs import FS_RANGE_HZ, sampling_rate

    ok = (not isinstance(value, bool | str | type(None)) and abs(value) < 1e308
          and FS_RANGE_HZ[0] <= value <= FS_RANGE_HZ[1])  # fmt: skip
    if ok:
        assert sampling_rate(value) == float(value)
    else:
        with pytest.raises(StiffnetError):
            sampling_rate(value)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.binary(max_size=300))
def test_recording_reader_never_crashes_and_never_echoes(tmp_path, data):
    from stiffnet.recordings import read_recording

    p = tmp_path / "x.csv"
    p.write_bytes(b"t,accel\n" + data)
    try:
        read_recording(p)
    except StiffnetError as exc:
        assert "\n" not in str(exc)


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(body=st.dictionaries(st.sampled_from(["samples", "fs_hz", "natural_frequency_hz", "x"]),
                            st.one_of(st.none(), st.booleans(), st.floats(), st.text(max_size=5),
                                      st.lists(st.floats(), max_size=5)), max_size=4))  # fmt: skip
def test_http_json_bodies_never_500(client, body):
    r = client.post("/predict", content=json.dumps(body).encode(),
                    headers={"content-type": "application/json"})  # fmt: skip
    assert 400 <= r.status_code < 500, r.text
    assert set(r.json()) == {"error"}
