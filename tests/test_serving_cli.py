"""``stiffnet predict`` and ``stiffnet serve``: output, one-line errors (exit 2), fuzzing."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from stiffnet.cli import app
from stiffnet.recordings import read_recording, write_recording_csv

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "recordings" / "impact_beta45.csv"
runner = CliRunner()


def _run(*args: str):
    return runner.invoke(app, [str(a) for a in args])


def test_predict_example_prints_the_cross_check(tmp_path):
    out = tmp_path / "r.json"
    res = _run("predict", EXAMPLE, "--json", out)
    assert res.exit_code == 0, res.output
    for text in ("hard", "geometric", "agreement", "alarm", "sidecar"):
        assert text in res.output
    r = json.loads(out.read_text())
    assert r["class"] == "hard" and r["natural_frequency_source"].startswith("sidecar:")


def test_predict_fn_option_and_gbm_model(tmp_path):
    out = tmp_path / "r.json"
    res = _run(
        "predict", EXAMPLE, "--fn", "9.48", "--model", ROOT / "models" / "gbm.onnx", "--json", out
    )
    assert res.exit_code == 0, res.output
    r = json.loads(out.read_text())
    assert r["natural_frequency_source"] == "option --fn" and r["model"]["kind"] == "gbm"


def _write(p: Path, text: str) -> Path:
    p.write_text(text)
    return p


def _csv(p: Path, a: np.ndarray, fs: float = 1000.0) -> Path:
    return write_recording_csv(p, a, fs)


@pytest.fixture(scope="module")
def accel():
    return read_recording(EXAMPLE).accel


def test_bad_inputs_give_one_line_and_exit_2(tmp_path, accel):
    d = tmp_path
    corrupt = d / "m"
    corrupt.mkdir()
    (corrupt / "cnn.onnx").write_bytes(b"not onnx")
    shutil.copy(ROOT / "models" / "cnn.card.json", corrupt / "cnn.card.json")
    npy = d / "r.npy"
    np.save(npy, accel)
    cases = {
        "empty": (_write(d / "e.csv", "t,accel\n"), [], "empty"),
        "one sample": (_write(d / "o.csv", "t,accel\n0,1\n"), [], "one sample"),
        "nan": (_write(d / "n.csv", "t,accel\n0,1\n0.001,nan\n0.002,1\n"), [], "finite"),
        "non-numeric": (_write(d / "x.csv", "t,accel\n0,1\n0.001,abc\n"), [], "not a number"),
        "header": (_write(d / "h.csv", "time,acc\n0,1\n"), [], "wrong header"),
        "extension": (_write(d / "r.txt", "t,accel\n"), [], "unknown recording extension"),
        "fs missing": (npy, [], "sampling rate missing"),
        "fs zero": (npy, ["--fs", "0"], "--fs must be in [0.01, 1e+08] Hz"),
        "fs negative": (npy, ["--fs", "-5"], "--fs must be in"),
        "short": (_csv(d / "s.csv", accel[:800]), [], "too short"),
        "constant": (_csv(d / "c.csv", np.ones(3000)), [], "constant"),
        "fn bad": (EXAMPLE, ["--fn", "-1"], "--fn must be in"),
        "corrupt model": (EXAMPLE, ["--model", corrupt / "cnn.onnx"], "does not match"),
        "missing": (d / "nope.csv", [], "not found"),
    }
    cases["fn missing"] = (_csv(d / "nofn.csv", accel), ["--no-fn"], "natural frequency unknown")
    for name, (path, extra, msg) in cases.items():
        if extra == ["--no-fn"]:
            extra = []
        elif "--fn" not in extra:
            extra = [*extra, "--fn", "9.48"]  # the checks after f_n's
        res = _run("predict", path, *extra)
        assert res.exit_code == 2, (name, res.output)
        lines = res.output.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error:"), (name, res.output)
        assert msg in res.output, (name, res.output)
        assert "Traceback" not in res.output


def test_clipped_recording_warns_but_predicts(tmp_path, accel):
    lim = 0.3 * np.abs(accel).max()
    res = _run("predict", _csv(tmp_path / "c.csv", np.clip(accel, -lim, lim)), "--fn", "9.48")
    assert res.exit_code == 0, res.output
    assert "clipped" in res.output


def test_serve_rejects_bad_limits():
    res = _run("serve", "--max-upload-mb", "0")
    assert res.exit_code == 2 and "max-upload-mb" in res.output


_cells = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(alphabet="0123456789.-e+ abcnaif,;\t", max_size=8),
)


@st.composite
def recordings(draw):
    """Random or malformed recording files: (name, bytes, extra CLI args)."""
    kind = draw(st.sampled_from(["csv", "csv_signal", "npy", "junk"]))
    if kind == "csv":
        header = draw(st.sampled_from(["t,accel", "t,acc", "", "t;accel", "T, Accel"]))
        rows = draw(st.lists(st.tuples(_cells, _cells), max_size=20))
        text = header + "\n" + "".join(f"{a},{b}\n" for a, b in rows)
        return "r.csv", text.encode(), []
    if kind == "csv_signal":
        n = draw(st.integers(2, 4000))
        fs = draw(st.sampled_from([100.0, 500.0, 1000.0, 2000.0]))
        seed = draw(st.integers(0, 2**16))
        x = np.random.default_rng(seed).standard_normal(n) * draw(st.sampled_from([1e-9, 1.0, 1e9]))
        text = "t,accel\n" + "".join(f"{i / fs!r},{float(v)!r}\n" for i, v in enumerate(x))
        return "r.csv", text.encode(), draw(st.sampled_from([[], ["--fn", "9.48"], ["--fn", "0"]]))
    if kind == "npy":
        import io

        arr = np.asarray(draw(st.lists(st.floats(width=32), max_size=50)), dtype=np.float32)
        buf = io.BytesIO()
        np.save(buf, arr)
        fs = draw(st.sampled_from(["1000", "0", "-1", "nan", "inf", "abc"]))
        return "r.npy", buf.getvalue(), ["--fs", fs]
    ext = draw(st.sampled_from([".csv", ".npy", ".wav", ".tdms", ".bin", ""]))
    return "r" + ext, draw(st.binary(max_size=200)), []


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(rec=recordings())
def test_cli_never_tracebacks(tmp_path, rec):
    name, data, extra = rec
    p = tmp_path / name
    p.write_bytes(data)
    res = _run("predict", p, *extra)
    assert res.exit_code in (0, 2), res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert "Traceback" not in res.output
    if res.exit_code == 2 and not res.output.startswith("Usage:"):  # click: --fs abc
        assert len(res.output.strip().splitlines()) == 1, res.output


def test_predict_wav_and_npy(tmp_path, accel):
    from scipy.io import wavfile

    scaled = np.round(accel / np.abs(accel).max() * 30000).astype(np.int16)
    wavfile.write(tmp_path / "r.wav", 1000, scaled)
    np.save(tmp_path / "r.npy", accel)
    for path, extra in ((tmp_path / "r.wav", []), (tmp_path / "r.npy", ["--fs", "1000"])):
        out = tmp_path / "r.json"
        res = _run("predict", path, *extra, "--fn", "9.48", "--json", out)
        assert res.exit_code == 0, res.output
        assert json.loads(out.read_text())["class"] == "hard"


def test_predict_reads_a_lab_layout_with_columns_and_time_unit(tmp_path, accel):
    lab = tmp_path / "lab.csv"
    rows = "\n".join(f"{k:d},{float(a)!r}" for k, a in enumerate(accel))  # time in ms
    lab.write_text("time_ms,acc_g\n" + rows + "\n")
    ref, got = tmp_path / "ref.json", tmp_path / "got.json"
    assert _run("predict", EXAMPLE, "--fn", "9.48", "--json", ref).exit_code == 0
    res = _run("predict", lab, "--fn", "9.48", "--columns", "time_ms,acc_g",
               "--time-unit", "ms", "--json", got)  # fmt: skip
    assert res.exit_code == 0, res.output
    assert json.loads(got.read_text())["beta"] == json.loads(ref.read_text())["beta"]
    # the plain call names the fix; seconds instead of ms names the unit mistake
    res = _run("predict", lab, "--fn", "9.48")
    assert res.exit_code == 2 and "--columns time_ms,acc_g --time-unit ms" in res.output
    res = _run("predict", lab, "--fn", "9.48", "--columns", "time_ms,acc_g")
    assert res.exit_code == 2 and "--time-unit ms" in res.output and "1000 Hz" in res.output
