"""The contract at every boundary: bad input is one line, exit 2 (HTTP 4xx JSON),
never a traceback nor a silently wrong output; outputs never destroy what is not theirs.

Each explicit case is one of the red-team findings; the hypothesis tests probe the
parsers with generated input.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import socket
import stat
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from live_server import serving
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
        one_line_error([*args, "--state", tmp_path / "loop", "--no-tracking"], "--n-trajectories")
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
    # the analysis brings an extreme signal to a peak in [0.5, 1) by a power of two (exact)
    assert huge == analyze_signal(np.ldexp(x / np.abs(x).max(), -1), rec.fs_hz).summary()
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


@pytest.fixture(scope="module")
def example_samples():
    from stiffnet.recordings import read_recording

    return read_recording(EXAMPLE).accel.tolist()


@pytest.mark.parametrize(
    "change",
    [
        {"samples": "bools"},  # [true, false, ...] was read as 1.0, 0.0
        {"fs_hz": "1000"},  # a string was read as a number
        {"fs_hz": True},
        {"fs_hz": 1e-306, "natural_frequency_hz": 1e-308},  # was the one 500
        {"natural_frequency_hz": True},  # was f_n = 1 Hz
    ],
)
def test_http_numbers_are_numbers(client, example_samples, change):
    body = {"samples": example_samples, "fs_hz": 1000, "natural_frequency_hz": 9.48}
    assert client.post("/predict", json=body).status_code == 200  # the valid request works
    body.update(change)
    if body["samples"] == "bools":
        body["samples"] = [bool(v > 0) for v in example_samples]
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


# ------------------------------------------------------------------ users' files are safe

TINY_SIM = (
    "n_trajectories: 4\nshard_size: 2\nwindows: {duration_periods: 4, per_trajectory: 1}\n"
    "sweep: {fs_ratio: [50, 60]}\nsolver: {settle_tolerance: 0.2}\n"
)


@pytest.fixture
def tiny_config(tmp_path):
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(TINY_SIM)
    return cfg


def _user_folder(folder: Path) -> dict[str, str]:
    (folder / "sub").mkdir(parents=True)
    (folder / "thesis.tex").write_text("years of work")
    (folder / "sub" / "notes.txt").write_text("notes")
    return {str(p.relative_to(folder)): p.read_text() for p in folder.rglob("*") if p.is_file()}


def _snapshot(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): p.read_text() for p in folder.rglob("*") if p.is_file()}


def test_overwrite_never_deletes_the_working_directory(tmp_path, monkeypatch):
    work = tmp_path / "work"
    before = _user_folder(work)
    (work / "campaign_card.json").write_text("{}")  # even with a marker: it is the cwd
    shutil.copy(ROOT / "examples" / "campaign_manifest.csv", tmp_path / "m.csv")
    monkeypatch.chdir(work)
    one_line_error(["simulate-campaign", tmp_path / "m.csv", "--out", ".", "--overwrite"],
                   "working directory")  # fmt: skip
    assert _snapshot(work) == {**before, "campaign_card.json": "{}"}


def test_overwrite_only_deletes_stiffnet_folders(tmp_path, tiny_config):
    other = tmp_path / "other"
    before = _user_folder(other)
    shutil.copy(ROOT / "examples" / "campaign_manifest.csv", tmp_path / "m.csv")
    one_line_error(["simulate-campaign", tmp_path / "m.csv", "--out", other, "--overwrite"],
                   "did not write")  # fmt: skip
    one_line_error(["simulate", "--config", tiny_config, "--out", other, "--overwrite"],
                   "did not write")  # fmt: skip
    assert _snapshot(other) == before


def test_json_never_replaces_links_fifos_or_devices(tmp_path, recording):
    target = tmp_path / "target.json"
    target.write_text("keep")
    link = tmp_path / "link.json"
    link.symlink_to(target)
    one_line_error(["analyze", recording, "--json", link], "symbolic link")
    assert link.is_symlink() and target.read_text() == "keep"
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    one_line_error(["analyze", recording, "--json", fifo], "not a regular file")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    from stiffnet.io_utils import write_json_atomic

    with pytest.raises(StiffnetError, match="refusing to replace"):
        write_json_atomic(link, {"a": 1})  # the library refuses too, not only the CLI
    assert link.is_symlink()


def test_concurrent_writers_are_refused_not_mixed(tmp_path, tiny_config):
    from stiffnet.io_utils import output_lock

    out = tmp_path / "ds"
    with output_lock(out):  # another run holds the folder
        one_line_error(["simulate", "--config", tiny_config, "--out", out, "--seed", "1"],
                       "another stiffnet run")  # fmt: skip
        one_line_error(["simulate", "--config", tiny_config, "--out", out, "--overwrite"],
                       "another stiffnet run")  # fmt: skip
        shutil.copy(ROOT / "examples" / "campaign_manifest.csv", tmp_path / "m.csv")
        one_line_error(["simulate-campaign", tmp_path / "m.csv", "--out", out],
                       "another stiffnet run")  # fmt: skip
    assert not out.exists()
    res = runner.invoke(app, ["simulate", "--config", str(tiny_config), "--out", str(out)])
    assert res.exit_code == 0, res.output  # released: the next run goes ahead


def test_load_dataset_refuses_a_mixed_folder(tmp_path):
    import yaml

    from stiffnet.config import validate_config
    from stiffnet.config.sim import SimulationConfig
    from stiffnet.dataset.generate import generate_dataset
    from stiffnet.dataset.store import load_dataset

    data = yaml.safe_load(TINY_SIM)
    a, b = tmp_path / "a", tmp_path / "b"
    generate_dataset(validate_config(SimulationConfig, {**data, "seed": 0}), a)
    generate_dataset(validate_config(SimulationConfig, {**data, "seed": 1}), b)
    assert len(load_dataset(a)) == 4
    shutil.copy(b / "shards" / "shard-00000.parquet", a / "shards" / "shard-00000.parquet")
    with pytest.raises(StiffnetError, match="does not match its SHA-256"):
        load_dataset(a)


def test_run_folders_replace_only_their_own_kind(tmp_path):
    from stiffnet.io_utils import RUN_MARKER, start_run_folder

    mine = tmp_path / "loop"
    start_run_folder(mine, "stiffnet-loop")
    (mine / "stale.png").write_text("from a killed run")
    start_run_folder(mine, "stiffnet-loop")  # the earlier run's files are gone, not mixed
    assert sorted(os.listdir(mine)) == [RUN_MARKER]
    user = tmp_path / "user"
    before = _user_folder(user)
    with pytest.raises(StiffnetError, match="not an earlier stiffnet-loop run"):
        start_run_folder(user, "stiffnet-loop")
    assert _snapshot(user) == before


def test_train_defaults_to_a_fresh_run_folder(tiny_dir, tmp_path, monkeypatch):
    """`train` without --out writes runs/train-gbm-TIME, never ./models (the shipped one)."""
    shipped = tmp_path / "models"
    shipped.mkdir()
    (shipped / "gbm.onnx").write_bytes(b"shipped")
    cfg = tmp_path / "gbm.yaml"
    cfg.write_text("gbm: {max_iter: 10, min_samples_leaf: 5}\ntracking: false\n")
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["train", "--data", str(tiny_dir), "--config", str(cfg)])
    assert res.exit_code == 0, res.output
    (run,) = (tmp_path / "runs").iterdir()
    assert run.name.startswith("train-gbm-") and (run / "gbm.onnx").is_file()
    assert (shipped / "gbm.onnx").read_bytes() == b"shipped"


def test_serve_beyond_loopback_warns(monkeypatch):
    """The warning line, without binding anything (tests bind 127.0.0.1 only)."""
    import uvicorn

    import stiffnet.cli.predict as sc

    monkeypatch.setattr(sc, "listen_socket", lambda host, port: None)
    monkeypatch.setattr(uvicorn.Server, "run", lambda self, sockets=None: None)
    model = str(ROOT / "models" / "gbm.onnx")
    res = runner.invoke(app, ["serve", "--host", "0.0.0.0", "--model", model])
    assert res.exit_code == 0, res.output
    assert "warning: listening on 0.0.0.0, beyond loopback" in res.stderr
    assert "no --token set" in res.stderr
    assert sc.is_loopback("127.0.0.1") and sc.is_loopback("::1") and sc.is_loopback("localhost")
    assert not sc.is_loopback("0.0.0.0") and not sc.is_loopback("192.168.1.5")


# --------------------------------------------------------------------- report and plug-ins


def test_report_embeds_no_foreign_file_and_escapes_keys(tmp_path):
    from stiffnet.measurement.report import render_report

    secret = tmp_path / "secret.png"
    secret.write_bytes(b"\x89PNG\r\n\x1a\nSECRET-BYTES")  # even a PNG outside the run folder
    diagnosis = {
        "baseline_discrepancy": 1.0,
        "missing_effect": "<script>alert(1)</script>",
        "ranking": [
            {
                "effect": "<b>x</b>",
                "params": {"<script>k</script>": 1.0},
                "fitted": [],
                "significant": True,
                "relative_reduction": 0.5,
                "discrepancy_reduction": 0.5,
            }
        ],
    }
    loop = {"before": {}, "after": {}, "effect": "x", "chart": str(secret), "out": str(tmp_path)}
    page = render_report("t", None, None, diagnosis, loop)
    assert "<script>" not in page and "&lt;script&gt;" in page
    import base64

    assert base64.b64encode(secret.read_bytes()).decode()[:20] not in page
    assert "loop chart not embedded" in page
    loop["chart"] = "/etc/passwd"
    assert "cm9vd" not in render_report("t", None, None, None, loop)  # base64 of "root"


def test_errors_never_echo_file_contents(tmp_path):
    from stiffnet.campaign import load_campaign
    from stiffnet.recordings import read_recording

    secret = tmp_path / "shadow"
    secret.write_text("admin:$6$SALTED$S3CRETHASH:19000:0:99999:7:::\nx\n")
    link = tmp_path / "r.csv"
    link.symlink_to(secret)
    with pytest.raises(StiffnetError) as exc:
        read_recording(link)
    assert "wrong header" in str(exc.value) and "S3CRET" not in str(exc.value)
    camp = tmp_path / "camp"
    camp.mkdir()
    (camp / "manifest.csv").symlink_to(secret)
    with pytest.raises(StiffnetError) as exc:
        load_campaign(camp)
    assert "admin" not in str(exc.value) and "S3CRET" not in str(exc.value)


def test_effect_names_never_import_from_the_path(tmp_path, monkeypatch):
    """A `module:Class` on sys.path (the working folder under `python -m`) never runs;
    an explicitly given plugin file does, and only after the rest of the config is valid."""
    from stiffnet.config import validate_config
    from stiffnet.config.sim import SimulationConfig
    from stiffnet.effects.registry import register_plugin
    from stiffnet.errors import ConfigError

    ran = tmp_path / "ran"
    (tmp_path / "evil_effect_mod.py").write_text(f"open({str(ran)!r}, 'w').write('ran')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    for effects in ([{"name": "evil_effect_mod:Evil"}], [{"name": "this:X"}]):
        with pytest.raises(ConfigError, match="not a registered stiffnet effect"):
            validate_config(SimulationConfig, {"effects": effects})
    assert not ran.exists() and "this" not in __import__("sys").modules
    one_line_error(
        [
            "simulate-campaign",
            ROOT / "examples" / "campaign_manifest.csv",
            "--out",
            tmp_path / "o",
            "--effect",
            "evil_effect_mod:Evil",
        ],
        "nothing was imported",
    )
    assert not ran.exists() and not (tmp_path / "o").exists()
    bad = {"seed": -1, "effects": [{"name": "evil_effect_mod:Evil"}]}
    register_plugin(tmp_path / "evil_effect_mod.py")  # the user names the file: it runs
    assert ran.exists()
    with pytest.raises(ConfigError, match="seed"):
        validate_config(SimulationConfig, bad)
    with pytest.raises(ConfigError, match="Evil"):  # no such class in it
        validate_config(SimulationConfig, {"effects": [{"name": "evil_effect_mod:Evil"}]})


def test_python_m_stiffnet_ignores_the_working_folder(tmp_path):
    """Under `python -m stiffnet` the cwd is on sys.path: an effect name still imports nothing."""
    import subprocess
    import sys

    (tmp_path / "evil.py").write_text("open('ran', 'w').write('ran')\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "STIFFNET_PLUGINS": ""}
    args = [
        sys.executable,
        "-m",
        "stiffnet",
        "simulate-campaign",
        str(ROOT / "examples" / "campaign_manifest.csv"),
        "--out",
        "o",
        "--effect",
        "evil:X",
    ]
    res = subprocess.run(args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "not a registered stiffnet effect" in res.stderr, res.stderr
    assert "Traceback" not in res.stderr and not (tmp_path / "ran").exists()
    plugin = tmp_path / "my_law.py"
    plugin.write_text("from stiffnet.effects.base import MeasurementEffect\n")
    res = subprocess.run(
        [*args[:3], "--plugin", str(plugin), *args[3:-1], "my_law:Nope"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert res.returncode == 2 and "'Nope' in 'my_law'" in res.stderr, res.stderr


# ------------------------------------------------------------------ the server under abuse


def test_serve_on_a_busy_port_is_one_line():
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        one_line_error(["serve", "--port", str(port)], "cannot listen on 127.0.0.1", "in use")


def test_bad_server_options_are_one_line():
    one_line_error(["serve", "--token", "short"], "--token must be at least 16")
    one_line_error(["serve", "--max-concurrency", "100000"], "--max-concurrency")
    one_line_error(["serve", "--max-samples", "0"], "--max-samples")


def test_large_requests_get_their_own_lane():
    """Over max_samples: 413; a big body beyond the large lane: 429 before it is read."""
    from fastapi.testclient import TestClient

    from serving.app import Limits, create_app
    from serving.predictor import Predictor

    limits = Limits(max_samples=5_000, small_upload_mb=0.01, max_large=1, max_large_queue=0)
    app = create_app(Predictor.load(ROOT / "models" / "gbm.onnx"), limits)
    with TestClient(app) as c:
        r = c.post("/predict", json={"samples": [0.0, 1.0] * 3000, "fs_hz": 1000})
        assert r.status_code == 413 and "at most 5000" in r.json()["error"]
        # occupy the only large slot, as a running upload would
        state = app.state.load
        state["large"] = 1
        r = c.post("/predict", json={"samples": [0.0, 1.0] * 3000, "fs_hz": 1000})
        assert r.status_code == 429 and "large" in r.json()["error"]
        small = {"samples": [0.0, 1.0] * 200, "fs_hz": 1000}
        assert c.post("/predict", json=small).status_code == 422  # the small lane still runs
        assert c.get("/health").json()["large_in_flight"] == 1


def test_token_host_and_cors_policy():
    from fastapi.testclient import TestClient

    from serving.app import create_app
    from serving.predictor import Predictor

    token = "s3cret-token-0123456789"
    policy = {"allowed_hosts": ["testserver"], "cors_origins": ["https://lab.example"]}
    app = create_app(Predictor.load(ROOT / "models" / "gbm.onnx"), token=token, **policy)
    with TestClient(app) as c:
        assert c.get("/health").status_code == 200  # liveness stays open
        r = c.get("/model")
        assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
        assert c.get("/model", headers={"Authorization": "Bearer nope"}).status_code == 401
        assert c.get("/model", headers={"Authorization": f"Bearer {token}"}).status_code == 200
        r = c.get("/health", headers={"Host": "evil.example"})  # DNS rebinding
        assert r.status_code == 400 and "host" in r.json()["error"]
        pre = {"Origin": "https://lab.example", "Access-Control-Request-Method": "POST"}
        r = c.options("/predict", headers=pre)
        assert r.headers.get("access-control-allow-origin") == "https://lab.example"
        r = c.options("/predict", headers={**pre, "Origin": "https://evil.example"})
        assert r.headers.get("access-control-allow-origin") is None
        html = c.get("/docs").text + c.get("/redoc").text
        assert "cdn" not in html.lower() and "/static-offline-docs/swagger-ui-bundle.js" in html
        assert c.get("/static-offline-docs/swagger-ui-bundle.js").status_code == 200


@pytest.fixture(scope="module")
def live_server(tmp_path_factory):
    log = tmp_path_factory.mktemp("serve") / "stderr.txt"
    model = str(ROOT / "models" / "gbm.onnx")
    with open(log, "wb") as err, serving("--model", model, "--body-timeout-s", "1",
                                         stderr=err) as port:  # fmt: skip
        yield port, log


def _raw(port: int, head: bytes, body: bytes = b"", close: bool = False, wait: float = 5.0):
    s = socket.create_connection(("127.0.0.1", port), timeout=wait)
    s.sendall(head + body)
    if close:
        s.close()
        return b""
    chunks = []
    try:
        while chunk := s.recv(65536):  # the server closes after its answer
            chunks.append(chunk)
    finally:
        s.close()
    return b"".join(chunks)


def test_slow_bodies_time_out_and_disconnects_log_one_line(live_server):
    import time

    port, log = live_server
    head = (b"POST /predict HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            b"Content-Length: 100000\r\n\r\n")  # fmt: skip
    t = time.monotonic()
    reply = _raw(port, head, b'{"samples": [1')  # and then nothing more
    assert reply.startswith(b"HTTP/1.1 408") and b'"error"' in reply
    assert time.monotonic() - t < 4  # --body-timeout-s 1
    for _ in range(5):
        _raw(port, head, b'{"samples": [1, 2', close=True)  # gone mid-body
    time.sleep(1.0)
    text = log.read_text()
    assert "Traceback" not in text
    assert text.count("disconnected before its request body was complete") == 5
    import httpx

    assert httpx.get(f"http://127.0.0.1:{port}/health").status_code == 200
    r = httpx.get(f"http://127.0.0.1:{port}/health", headers={"Host": "rebind.example"})
    assert r.status_code == 400  # serve allows only loopback names by default
