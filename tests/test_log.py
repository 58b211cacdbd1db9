"""``stiffnet log``: beta along a record, layers, change times, online = offline."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from drill_records import FN_HZ, layered_record

from serving.log import StiffnessLogger, stiffness_log
from serving.predictor import Predictor
from serving.stream import sample_chunks
from stiffnet.errors import StiffnetError
from stiffnet.geometry.calibration import DEFAULT_CLASSES
from stiffnet.layers import change_points, class_with_hysteresis, noise_scale
from stiffnet.recordings import write_recording_csv

FS = 2000.0
ROOT = Path(__file__).resolve().parents[1]

#: name -> (betas, durations): 0, 1 and 2 changes, across class edges (soft/medium at 15)
CASES = {
    "constant": ([40.0], [60.0]),
    "soft_to_hard": ([10.0, 45.0], [30.0, 30.0]),
    "two_changes": ([25.0, 50.0, 12.0], [20.0, 20.0, 20.0]),
    "across_edge": ([13.0, 17.5], [30.0, 30.0]),
}


@pytest.fixture(scope="module")
def predictor() -> Predictor:
    return Predictor.load()


@pytest.fixture(scope="module")
def records() -> dict[str, tuple[np.ndarray, list[float], list[float]]]:
    out = {}
    for i, (name, (betas, durs)) in enumerate(CASES.items()):
        a, changes = layered_record(betas, durs, noise=0.03, seed=100 + i)
        out[name] = (a, changes, betas)
    return out


@pytest.mark.parametrize("name", list(CASES))
def test_layers_found_with_times_and_betas(predictor, records, name):
    a, changes, betas = records[name]
    log = stiffness_log(predictor, a, FS, FN_HZ)
    assert log["hop_s"] <= 0.5
    assert len(log["layers"]) == len(betas), [la["beta"] for la in log["layers"]]
    assert len(log["changes"]) == len(changes)
    for found, true in zip(log["changes"], changes, strict=True):
        assert abs(found["t_s"] - true) <= 1.0
        assert 0 < found["sd_s"] <= 2.0
    for layer, beta in zip(log["layers"], betas, strict=True):
        assert abs(layer["beta"] / beta - 1) <= 0.10, (layer["beta"], beta)
        lo, hi = layer["beta_interval"]
        assert lo < layer["beta"] < hi
    # the layers tile the record
    assert log["layers"][0]["start_s"] == 0.0
    assert log["layers"][-1]["end_s"] == pytest.approx(a.size / FS)
    for a_, b_ in zip(log["layers"], log["layers"][1:], strict=False):
        assert a_["end_s"] == b_["start_s"]
    changed = [w for w in log["warnings"] if w.startswith("beta changes along this record")]
    assert bool(changed) == (len(betas) > 1)
    assert all(la["drift"] is None for la in log["layers"])  # steps, not ramps
    assert not [w for w in log["warnings"] if w.startswith("the alarm fired on most windows")]
    # a point's interval widened by the alarm is said, and rare on a right layer (the constant
    # record: one point of 117, the restoring force's interval 28.2-42.7 across the edge at 35)
    for w in log["warnings"]:
        if w.startswith("the alarm widened"):
            assert int(re.search(r"of (\d+) point", w).group(1)) <= 0.02 * log["n_points"]


def test_a_gradual_transition_is_said_to_drift_not_taken_for_a_layer(predictor):
    """beta 15 -> 55 over 8 s (sixteen 0.5 s steps): the log called the ramp a layer of
    its mean beta with nothing said; the layer that holds the ramp now says it drifts."""
    ramp = list(np.linspace(15.0, 55.0, 18)[1:-1])
    a, _ = layered_record([15.0, *ramp, 55.0], [20.0, *[0.5] * len(ramp), 20.0], seed=7)
    log = stiffness_log(predictor, a, FS, FN_HZ)
    drifting = [la for la in log["layers"] if la["drift"] is not None]
    assert drifting, [(la["start_s"], la["end_s"], la["beta"]) for la in log["layers"]]
    for la in drifting:
        d = la["drift"]
        assert 15.0 <= d["from_beta"] < d["to_beta"] <= 60.0
        assert 19.0 <= d["from_s"] < d["to_s"] <= 29.5  # inside the ramp, give or take a window
    assert any("a gradual transition, not a layer of one beta" in w for w in log["warnings"])


def test_points_carry_interval_alarm_and_restoring_force(predictor, records):
    a, _, _ = records["soft_to_hard"]
    log = stiffness_log(predictor, a, FS, FN_HZ, hop_s=0.25, restoring_force_every_s=5.0)
    pts = log["points"]
    t = np.array([p["t_s"] for p in pts])
    assert np.allclose(np.diff(t), 0.25)
    assert all(p["beta_interval"][0] < p["beta"] < p["beta_interval"][1] for p in pts)
    assert all(isinstance(p["alarm"], bool) for p in pts)
    checked = [p for p in pts if "restoring_force" in p]
    assert 10 <= len(checked) <= 13  # one every 5 s
    # the restoring force inside each layer agrees with it
    for layer in log["layers"]:
        assert (
            layer["restoring_force"]["n_checks"] >= 3
            and layer["restoring_force"]["agreement"] is True
        )


def test_chunked_stream_gives_the_same_layers(predictor, records):
    a, _, _ = records["two_changes"]
    whole = stiffness_log(predictor, a, FS, FN_HZ)
    rng = np.random.default_rng(0)
    log = StiffnessLogger(predictor, FS, FN_HZ)
    events, lo = [], 0
    while lo < a.size:
        n = int(rng.integers(1, 5000))
        events += log.feed(a[lo : lo + n])
        lo += n
    events += log.finish()
    layers = [e for k, e in events if k == "layer"]
    assert json.dumps(layers) == json.dumps(whole["layers"])
    points = [e for k, e in events if k == "point"]
    assert len(points) == len(whole["points"])
    # a layer is emitted before the stream ends: the first closes while the third is read
    first = next(i for i, (k, _) in enumerate(events) if k == "layer")
    assert first < len(events) - 3


def test_memory_stays_bounded(predictor):
    a, _ = layered_record([30.0], [30.0], seed=5)
    log = StiffnessLogger(predictor, FS, FN_HZ)
    log.segmenter.max_points = 40  # fold early: an endless stream keeps sums, not points
    for _ in range(4):
        log.feed(a)
        assert log.buf.size <= log.n_win + log.hop + a.size
        assert len(log.segmenter.points) <= 60
    layers = [e for k, e in log.finish() if k == "layer"]
    assert len(layers) >= 1 and abs(layers[-1]["beta"] / 30 - 1) < 0.15


def test_hysteresis_keeps_the_class_near_an_edge():
    classes = DEFAULT_CLASSES
    assert class_with_hysteresis(15.5, "soft", classes) == ("soft", True)
    assert class_with_hysteresis(15.5, None, classes) == ("medium", True)
    assert class_with_hysteresis(17.0, "soft", classes) == ("medium", False)
    assert class_with_hysteresis(40.0, "soft", classes)[0] == "hard"  # not a neighbour


def test_change_points_on_a_step():
    rng = np.random.default_rng(1)
    x = np.r_[np.zeros(100), np.ones(100)] + 0.1 * rng.standard_normal(200)
    z = x / noise_scale(x, 1)
    assert change_points(z, 20.0, 5) == [100]
    assert change_points(rng.standard_normal(300), 30.0, 5) == []


def test_stream_decoding(tmp_path):
    p = tmp_path / "s.csv"
    p.write_bytes(b"t,accel\n0,1.5\n0.001,2.5\n\n0.002,-1\n")
    assert np.concatenate(list(sample_chunks(p, idle_timeout_s=0.1))).tolist() == [1.5, 2.5, -1.0]
    p.write_bytes(b"1\n2\nx\n")
    with pytest.raises(Exception, match="line 3 is not a sample"):
        list(sample_chunks(p, idle_timeout_s=0.1))
    # a European spreadsheet's export: split at its decimal commas, '0,001;2,5' read 5 (the
    # fraction's digits) as the sample, a log of garbage with exit 0
    for text, word in ((b"t;accel\n0,000;1,5\n0,001;2,5\n", "';'"), (b"0\t1.5\n", "tabs")):
        p.write_bytes(text)
        with pytest.raises(Exception, match=f"line 1: its cells are separated by {word}"):
            list(sample_chunks(p, idle_timeout_s=0.1))
    f = tmp_path / "s.f32"
    np.arange(5, dtype="<f4").tofile(f)
    got = np.concatenate(list(sample_chunks(f, "f32", idle_timeout_s=0.1)))
    assert got.tolist() == [0, 1, 2, 3, 4]


@pytest.mark.parametrize(("header", "step"), [(b"t,accel", 1e-3), (b"time_ms,acc_g", 1.0)])
def test_a_streams_time_column_contradicting_the_rate_is_refused(tmp_path, header, step):
    """A growing file 't,accel' at 1 kHz followed with --fs 2000 was read at 2 kHz in
    silence (its time column skipped): a 15 -> 20.6 beta, the alarm on every window."""
    p = tmp_path / "s.csv"
    lines = [f"{i * step:.6g},{np.sin(i / 7):.4f}".encode() for i in range(200)]
    p.write_bytes(header + b"\n" + b"\n".join(lines) + b"\n")
    with pytest.raises(StiffnetError, match=r"its time column '(t|time_ms)' gives 1000 Hz "
                       r"\(up to line 65\) but --fs 2000 was given"):  # fmt: skip
        list(sample_chunks(p, idle_timeout_s=0.1, fs_hz=2000.0))
    got = np.concatenate(list(sample_chunks(p, idle_timeout_s=0.1, fs_hz=1000.0)))
    assert got.size == 200  # the right rate: every sample
    # the time column read as the samples (column 0) or no rate given: nothing to check
    assert np.concatenate(list(sample_chunks(p, idle_timeout_s=0.1, column=0))).size == 200


def _cli(*args, stdin=None, **kw):
    return subprocess.run([sys.executable, "-m", "stiffnet", "log", *args], input=stdin,
                          capture_output=True, cwd=ROOT, timeout=120, **kw)  # fmt: skip


@pytest.mark.slow
def test_cli_offline_outputs_and_follow_stdin(records, tmp_path):
    a, changes, _ = records["soft_to_hard"]
    rec = write_recording_csv(tmp_path / "drill.csv", a, FS)
    r = _cli(str(rec), "--fn", str(FN_HZ), "--json", str(tmp_path / "log.json"),
             "--rows", str(tmp_path / "log.csv"), "--plot", str(tmp_path / "log.png"))  # fmt: skip
    assert r.returncode == 0, r.stderr.decode()
    assert b"change at 30" in r.stdout
    doc = json.loads((tmp_path / "log.json").read_text())
    rows = (tmp_path / "log.csv").read_text().splitlines()
    assert len(rows) == 1 + doc["n_points"] and rows[0].startswith('"t_s","beta"')
    assert (tmp_path / "log.png").read_bytes()[:4] == b"\x89PNG"
    # the same record as raw float32 on stdin: the same layers, as NDJSON lines
    r = _cli("-", "--follow", "--fs", "2000", "--fn", str(FN_HZ), "--stream-format", "f32",
             stdin=a.astype("<f4").tobytes())  # fmt: skip
    assert r.returncode == 0, r.stderr.decode()
    events = [json.loads(line) for line in r.stdout.decode().splitlines()]
    layers = [e for e in events if e["type"] == "layer"]
    assert [round(la["end_s"], 3) for la in layers] == [
        round(la["end_s"], 3) for la in doc["layers"]
    ]


@pytest.mark.slow
def test_cli_follows_a_growing_file(records, tmp_path):
    a, _, _ = records["soft_to_hard"]
    path = tmp_path / "daq.csv"
    path.write_text("")
    text = "".join(f"{float(v)!r}\n" for v in a).encode()

    def writer():
        with open(path, "ab") as fh:
            for lo in range(0, len(text), 200_000):
                fh.write(text[lo : lo + 200_000])
                fh.flush()
                time.sleep(0.05)

    th = threading.Thread(target=writer)
    th.start()
    r = _cli(str(path), "--follow", "--fs", "2000", "--fn", str(FN_HZ), "--idle-timeout", "1.5")
    th.join()
    assert r.returncode == 0, r.stderr.decode()
    layers = [json.loads(x) for x in r.stdout.decode().splitlines() if b'"layer"' in x.encode()]
    assert len(layers) == 2 and abs(layers[0]["end_s"] - 30.0) <= 1.0


def test_cli_refuses_without_natural_frequency_or_rate(records, tmp_path):
    a, _, _ = records["constant"]
    rec = write_recording_csv(tmp_path / "r.csv", a[:20000], FS)
    r = _cli(str(rec))
    assert r.returncode == 2 and b"natural frequency unknown" in r.stderr
    assert b"Traceback" not in r.stderr and len(r.stderr.decode().strip().splitlines()) == 1
    r = _cli("-", "--follow", "--fn", "9.48", stdin=b"")
    assert r.returncode == 2 and b"--follow needs --fs" in r.stderr
    r = _cli(str(rec), "--fn", "9.48", "--sensor", "lowpass_hz=120,gain=2")
    assert r.returncode == 2 and b"unknown sensor key(s) gain" in r.stderr
    assert len(r.stderr.decode().strip().splitlines()) == 1
    r = _cli(str(rec), "--fn", "9.48", "--restoring-force-every", "-5")
    assert r.returncode == 2 and b"--restoring-force-every must be >= 0 s" in r.stderr
    assert len(r.stderr.decode().strip().splitlines()) == 1


def test_the_logs_defaults_come_from_its_shipped_settings():
    """configs/log.yaml validates, is what the log uses by default, and a hop above the
    design's limit or an unknown key is refused in one line."""
    from pydantic import ValidationError

    from serving.log import LogSettings, log_settings
    from stiffnet.config import load_config

    shipped = load_config(LogSettings, ROOT / "configs/log.yaml")
    assert shipped == log_settings()
    log = StiffnessLogger(Predictor.load(), FS, FN_HZ)
    assert log.hop_s == pytest.approx(shipped.hop_s, abs=1 / FS)
    assert log.restoring_force_every == round(shipped.restoring_force_every_s * FS)
    with pytest.raises(ValidationError):
        LogSettings(hop_s=0.75)
    with pytest.raises(ValidationError):
        LogSettings(batch_size=64)


def _through_chain(a: np.ndarray, **stages: float) -> np.ndarray:
    """`a` as an accelerometer behind the chain `stages` records it."""
    from scipy import signal

    from stiffnet.restoring_force.chain import SensorChain, chain_sos

    return signal.sosfilt(chain_sos(SensorChain(**stages), FS), a)


def _layer_betas(doc: dict) -> list[float]:
    return [la["beta"] for la in doc["layers"]]


def test_a_data_sheets_chain_is_divided_out_of_every_window_in_any_chunking(predictor):
    """Soft then hard rock behind a mount resonance at 10 f_n and a 3rd-order low-pass at
    0.06 fs: read as recorded the log is far off (both layers read above 50); with the data
    sheet it reads the layers of the clean record, and a stream cut anywhere reads the
    same points."""
    clean, _ = layered_record([12.0, 60.0], [10.0, 10.0], seed=3)
    sheet = {"resonance_hz": 10 * FN_HZ, "resonance_damping": 0.05, "lowpass_hz": 0.06 * FS,
             "lowpass_order": 3}  # fmt: skip
    rec = _through_chain(clean, **sheet)
    truth = stiffness_log(predictor, clean, FS, FN_HZ, restoring_force_every_s=None)
    read = stiffness_log(predictor, rec, FS, FN_HZ, restoring_force_every_s=None, sensor=sheet)
    assert read["chain_undone"]["source"] == "data sheet" and read["chain_readings"] is None
    assert _layer_betas(read) == pytest.approx(_layer_betas(truth), rel=0.1)
    logger = StiffnessLogger(predictor, FS, FN_HZ, restoring_force_every_s=None, fit_chain=False)
    as_recorded = [it for chunk in (rec,) for k, it in logger.feed(chunk) if k == "point"]
    assert np.median([p["beta"] for p in as_recorded[:20]]) > 50  # truth 12
    logger = StiffnessLogger(predictor, FS, FN_HZ, restoring_force_every_s=None,
                             sensor=sheet)  # fmt: skip
    events = [e for chunk in np.array_split(rec, 37) for e in logger.feed(chunk)]
    points = [it for k, it in events + logger.finish() if k == "point"]
    assert [p["beta"] for p in points] == pytest.approx([p["beta"] for p in read["points"]])


@pytest.mark.slow
def test_a_chain_fitted_on_the_records_start_is_undone_and_the_intervals_span_it(predictor):
    """No data sheet: the 3rd-order low-pass at 120 Hz is identified on the record's first
    24 periods (read 145 Hz: the fit reads corners high), divided out of every window, and
    each point's and layer's interval spans the readings through the other chains the fit
    stands for (as recorded, the corner at 0.8 and 0.9 of the fitted one)."""
    from serving.chain_spread import ChainSpreadConfig

    clean, _ = layered_record([12.0, 60.0], [10.0, 10.0], seed=3)
    rec = _through_chain(clean, lowpass_hz=0.06 * FS, lowpass_order=3)
    doc = stiffness_log(predictor, rec, FS, FN_HZ, restoring_force_every_s=None)
    assert doc["chain_undone"]["source"] == "fitted"
    assert doc["chain_undone"]["lowpass_hz"] == pytest.approx(120.0, rel=0.3)
    assert doc["chain_readings"] and any("fitted on the record" in w for w in doc["warnings"])
    alone = Predictor.load(chain_spread=ChainSpreadConfig(enabled=False))
    own = stiffness_log(alone, rec, FS, FN_HZ, restoring_force_every_s=None)
    assert own["chain_readings"] is None
    assert [p["beta"] for p in doc["points"]] == pytest.approx([p["beta"] for p in own["points"]])
    wider = 0
    for spread, narrow in zip(doc["points"] + doc["layers"], own["points"] + own["layers"],
                              strict=True):  # fmt: skip
        (lo, hi), (lo0, hi0) = spread["beta_interval"], narrow["beta_interval"]
        assert lo <= lo0 * (1 + 1e-9) and hi >= hi0 * (1 - 1e-9)
        wider += lo < lo0 * 0.99 or hi > hi0 * 1.01
    assert wider >= len(doc["points"]) // 2


@pytest.mark.slow
def test_log_on_an_independent_rig_whose_motion_carries_across_the_change():
    """Layers of records from tests/independent_rig.py (solve_ivp, SI units, Kelvin-Voigt
    contact): the state carries on across each change, so the orbit settles into the new
    layer over a few periods - a transition that must not pass for a layer of its own."""
    from independent_rig import RigRun, record

    cases = [([], 30.0, [30.0]), ([(15.0, 45.0)], 10.0, [10.0, 45.0]),
             ([(12.0, 50.0), (26.0, 12.0)], 25.0, [25.0, 50.0, 12.0])]  # fmt: skip
    for schedule, first, betas in cases:
        run = RigRun("drill.csv", beta=first, fs_hz=2000.0, duration_s=40.0,
                     contact="kelvin_voigt", contact_zeta=0.1, noise=0.03)  # fmt: skip
        _, a = record(run, beta_schedule=schedule)
        log = stiffness_log(Predictor.load(), a, FS, FN_HZ, restoring_force_every_s=None)
        got = [la["beta"] for la in log["layers"]]
        assert len(got) == len(betas), got
        for found, (true, _) in zip(log["changes"], schedule, strict=True):
            assert abs(found["t_s"] - true) <= 1.0
        for layer, beta in zip(log["layers"], betas, strict=True):
            assert abs(layer["beta"] / beta - 1) <= 0.10, (layer["beta"], beta)


def test_a_log_point_gets_the_predictors_checks_and_its_wider_interval(predictor, monkeypatch):
    """A point whose restoring-force check contradicts the model fires the predictor's rule
    checks and reports the wider interval behind an alarm (one verdict for both commands);
    the points without a check keep the model's conformal interval."""
    import serving.log as log_module
    from serving.verdict import model_facts, rule_checks

    a, _ = layered_record([40.0], [30.0], noise=0.03, seed=11)
    calm = stiffness_log(predictor, a, FS, FN_HZ, restoring_force_every_s=None)
    lo = min(p["beta_interval"][0] for p in calm["points"])
    far = {"class": "soft", "beta": 0.3 * lo, "beta_interval": [0.25 * lo, 0.35 * lo],
           "contact_r2": 0.99, "duration_ratio": 1.1, "reason": "contradicting (test)"}  # fmt: skip
    monkeypatch.setattr(log_module, "restoring_force_check", lambda *a, **k: far)
    log = stiffness_log(predictor, a, FS, FN_HZ, restoring_force_every_s=5.0)
    checked = [p for p in log["points"] if "restoring_force" in p]
    assert len(checked) >= 4
    by_t = {p["t_s"]: p for p in calm["points"]}
    for p in checked:
        assert {"restoring_force", "restoring_force_class"} <= set(p["alarm_fired"])
        assert p["alarm"]
        assert p["beta_interval"] == pytest.approx([0.25 * lo, by_t[p["t_s"]]["beta_interval"][1]])
        # the predictor's verdict on the same answer and cross-check fires the same rule checks
        quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
        same = rule_checks(quiet, p["class"], by_t[p["t_s"]]["beta_interval"], far,
                           model_facts(predictor), FS, FN_HZ)  # fmt: skip
        assert set(same["fired"]) <= set(p["alarm_fired"])
    for p in log["points"]:
        if "restoring_force" not in p:
            assert p["beta_interval"] == by_t[p["t_s"]]["beta_interval"]
            assert p["alarm_fired"] == by_t[p["t_s"]]["alarm_fired"]
    assert any(f"{len(checked)} point(s)" in w and "widened" in w for w in log["warnings"])
    assert not any("widened" in w for w in calm["warnings"])


def test_a_flagged_layer_reports_the_wider_interval_behind_its_alarm(predictor, monkeypatch):
    """A layer whose points mostly raised the alarm is a flagged recording: its interval spans
    its close-fitting restoring-force interval too, as predict's does, and a warning says so."""
    import serving.log as log_module

    a, _ = layered_record([40.0], [30.0], noise=0.03, seed=11)
    calm = stiffness_log(predictor, a, FS, FN_HZ, restoring_force_every_s=None)
    (layer,) = calm["layers"]
    lo, hi = layer["beta_interval"]
    far = {"class": "soft", "beta": 0.3 * lo, "beta_interval": [0.25 * lo, 0.35 * lo],
           "contact_r2": 0.99, "duration_ratio": 1.1, "reason": "contradicting (test)"}  # fmt: skip
    monkeypatch.setattr(log_module, "restoring_force_check", lambda *a, **k: far)
    log = stiffness_log(predictor, a, FS, FN_HZ, restoring_force_every_s=0.5)  # every point
    (flagged,) = log["layers"]
    assert flagged["alarm"] and flagged["alarm_fraction"] == 1.0
    assert flagged["restoring_force"]["contact_r2"] == pytest.approx(0.99)
    assert flagged["beta_interval"] == pytest.approx([0.25 * lo, hi])
    assert any("flagged layer(s) 0 is widened" in w for w in log["warnings"])
    # a loose contact-law fit is weak evidence: the layer keeps the model's interval
    monkeypatch.setattr(
        log_module, "restoring_force_check", lambda *a, **k: {**far, "contact_r2": 0.8}
    )
    loose = stiffness_log(predictor, a, FS, FN_HZ, restoring_force_every_s=0.5)
    assert loose["layers"][0]["beta_interval"] == pytest.approx([lo, hi])
    assert not any("widened" in w for w in loose["warnings"])


def test_the_checks_along_a_record_fit_its_chain_once(predictor, monkeypatch):
    """Soft then hard rock, no chain: the hard layer's contact law explains under 98 % as
    recorded (13 samples a contact), so every check there used to fit a chain (1-3 s each)
    and find none. The first fit decides the record's chain; the later checks read through
    it, and read what the window reads alone."""
    import stiffnet.restoring_force.estimate as estimate

    fits = []
    real = estimate.fit_chain

    def counted(*args, **kwargs):
        fits.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(estimate, "fit_chain", counted)
    a, _ = layered_record([20.0, 50.0], [60.0, 60.0], seed=11)
    doc = stiffness_log(predictor, a, FS, FN_HZ, restoring_force_every_s=10.0)
    hard = doc["layers"][-1]["restoring_force"]
    assert len(fits) == 1 and hard["n_checks"] >= 5
    assert hard["beta"] == pytest.approx(50.0, rel=0.1) and hard["agreement"]
    from serving.restoring_force_check import restoring_force_check

    last = [p for p in doc["points"] if "restoring_force" in p][-1]
    n_win = StiffnessLogger(predictor, FS, FN_HZ).n_win
    end = int(round(last["t_s"] * FS)) + n_win // 2
    own = restoring_force_check(a[end - n_win : end], FS, FN_HZ)  # the window, read alone
    assert last["restoring_force"]["beta"] == pytest.approx(own["beta"], rel=0.05)


def test_a_chain_found_after_the_records_start_is_held_and_said(predictor):
    """A check that fits a low-pass the start did not show: the later checks read through it
    as through a data sheet (its corner and high-pass held), and a warning says the model
    reads the record as recorded; a fit that applies no stage holds only its high-pass."""
    log = StiffnessLogger(predictor, FS, FN_HZ)
    found = {"source": "fitted", "applied": True, "resonance_hz": None, "lowpass_hz": 131.0,
             "lowpass_order": 3.2, "highpass_hz": 0.4}  # fmt: skip
    log._hold_chain(found, 42.0)
    assert log.check_chain_known and log.check_highpass is None
    assert log.check_sheet["lowpass_hz"] == 131.0 and log.check_sheet["lowpass_order"] == 3.0
    assert log.check_sheet["highpass_hz"] == 0.4
    assert any("at 42 s" in w and "low-pass 131 Hz" in w for w in log.warnings)
    log = StiffnessLogger(predictor, FS, FN_HZ)
    log._hold_chain({"source": "data sheet", "lowpass_hz": 131.0}, 42.0)  # not a fit
    assert not log.check_chain_known
    log._hold_chain({"source": "fitted", "applied": False, "lowpass_hz": 90.0,
                     "highpass_hz": 1.5}, 42.0)  # fmt: skip
    assert log.check_chain_known and log.check_sheet is None and log.check_highpass == 1.5
    assert not log.warnings


def test_a_fit_rejected_by_a_check_that_read_nothing_leaves_the_chain_to_a_later_check(
    predictor, monkeypatch
):
    """A drilling record's start-up (no steady impacts yet) fits a chain it rejects and reads
    no beta: that says nothing of the sensor, so the next check's fit is the record's. Held,
    it had left a record behind a 240 Hz mount as recorded throughout (a beta-60 layer read
    92.5 by the model, every check refused)."""
    import serving.log as log_module

    start = {"beta": None, "sensor": {"source": "fitted", "applied": False, "lowpass_hz": 64.5,
             "lowpass_order": 3, "resonance_hz": None, "highpass_hz": 0.0}}  # fmt: skip
    steady = {"beta": 60.0, "sensor": {"source": "fitted", "applied": True, "lowpass_hz": 416.0,
              "lowpass_order": 3, "resonance_hz": 240.4, "resonance_damping": 0.05,
              "highpass_hz": 0.0}}  # fmt: skip
    checks = iter([start, steady])
    monkeypatch.setattr(log_module, "restoring_force_check", lambda *a, **k: next(checks))
    log = StiffnessLogger(predictor, FS, FN_HZ)
    seg = np.zeros(log.n_win)
    log._check(seg, 0.0)
    assert not log.check_chain_known and log.check_sheet is None
    log._check(seg, 9.3)
    assert log.check_chain_known and log.check_sheet["resonance_hz"] == pytest.approx(240.4)
    assert log.found_late is not None and log.found_late[1] == 9.3


def test_the_whole_records_chain_scan_shows_its_own_progress(predictor):
    """The scan for a chain runs every check before the log's first point: a progress line
    of its own counts them (the log's bar would otherwise wait at zero, silent)."""
    from stiffnet import progress

    class Lines:
        def __init__(self):
            self.lines = {}

        def add_task(self, description, total=None, **fields):
            self.lines[description] = {"total": total, "done": 0}
            return description

        def update(self, task_id, advance=0, **kwargs):
            self.lines[task_id]["done"] += advance

        def remove_task(self, task_id):
            pass

    clean, _ = layered_record([12.0], [30.0], seed=3)  # no chain: every check is run
    log = StiffnessLogger(predictor, FS, FN_HZ, restoring_force_every_s=5.0)
    lines = Lines()
    with progress.reporting(lines):
        log.scan_chain(clean)
    scan = lines.lines["looking for the sensor chain"]
    assert scan["total"] == len(log.checks_ahead) == scan["done"] >= 4


@pytest.mark.slow
def test_a_whole_records_log_reads_it_through_a_chain_its_start_did_not_show(predictor):
    """Soft then hard rock behind a 94.8 Hz mount (10 f_n) and a 120 Hz 3rd-order low-pass:
    the start's check fits no chain (the soft pulse passes), a later one fits the mount. A
    whole record is scanned first, so the model reads all of it through that mount: the soft
    layer reads soft (as recorded it read very hard, 91). A stream cannot go back: it warns
    and reads as recorded. Both run the same checks with the same readings."""
    clean, _ = layered_record([12.0, 60.0], [40.0, 40.0], seed=3)
    rec = _through_chain(clean, resonance_hz=10 * FN_HZ, resonance_damping=0.05,
                         lowpass_hz=0.06 * FS, lowpass_order=3)  # fmt: skip
    doc = stiffness_log(predictor, rec, FS, FN_HZ, restoring_force_every_s=5.0)
    assert doc["chain_undone"]["resonance_hz"] == pytest.approx(10 * FN_HZ, rel=0.05)
    assert any("fitted by the check at" in w for w in doc["warnings"])
    soft = doc["layers"][0]
    assert soft["class"] == "soft" and soft["beta"] == pytest.approx(12.0, rel=0.15)
    logger = StiffnessLogger(predictor, FS, FN_HZ, restoring_force_every_s=5.0)
    events = [e for chunk in np.array_split(rec, 9) for e in logger.feed(chunk)]
    streamed = [it for k, it in events + logger.finish() if k == "point"]
    assert any("the model reads the record as recorded" in w for w in logger.warnings)
    checks = [p["restoring_force"]["beta"] for p in doc["points"] if "restoring_force" in p]
    assert checks == [p["restoring_force"]["beta"] for p in streamed if "restoring_force" in p]


def test_the_layers_check_counts_what_the_layers_report():
    """Two neighbouring layers without contact report the same (no contact, no beta): no
    change; a contact starting or beta changing is one."""
    from serving.log import LAYERS_CHECK, reported_changes, with_layers_alarm

    none = {"class": "no_contact", "beta": None}
    soft, hard = {"class": "soft", "beta": 12.0}, {"class": "hard", "beta": 45.0}
    assert reported_changes([none, none, none]) == 0
    assert reported_changes([none, soft, hard]) == 2
    assert reported_changes([soft, none, none, hard]) == 2
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}, "message": ""}
    assert with_layers_alarm(quiet, [none, none]) is quiet
    layered = [
        {**la, "start_s": 5.0 * i, "end_s": 5.0 * i + 5} for i, la in enumerate([none, none, soft])
    ]
    res = with_layers_alarm(quiet, layered)
    assert res["fired"] == [LAYERS_CHECK] and res["scores"][LAYERS_CHECK] == 1.0


def test_a_dropout_is_said_and_flags_the_points_that_read_it(predictor, records):
    """Half a second of zeros in a record (a loose cable; a logger filling its gap) was read
    as the rig's motion with nothing said, by the log and by predict (an independent rig's
    40-s drilling record: four points over 21.3-22.8 s, beta 50.1-52.7 for 55, no alarm)."""
    a, _, _ = records["constant"]
    held = a.copy()
    held[int(22.0 * FS) : int(22.5 * FS)] = 0.0
    log = stiffness_log(predictor, held, FS, FN_HZ)
    flagged = [p["t_s"] for p in log["points"] if "dropout" in p["alarm_fired"]]
    # the points whose 1.69 s windows overlap 22.0-22.5 s, and only those
    half = 0.5 * log["window_s"]
    assert flagged and all(22.0 - half < t < 22.5 + half for t in flagged), flagged
    assert all(p["alarm"] for p in log["points"] if p["t_s"] in flagged)
    said = [w for w in log["warnings"] if "a dropout" in w]
    assert len(said) == 1 and "(0) for 0.5 s in 1 run(s)" in said[0] and "22.00-22.50 s" in said[0]
    assert f"the {len(flagged)} point(s)" in said[0]
    # the record without it says nothing of the kind
    clean = stiffness_log(predictor, a, FS, FN_HZ)
    assert not any("dropout" in p["alarm_fired"] for p in clean["points"])
    assert not any("dropout" in w for w in clean["warnings"])
    result = predictor.predict(held, FS, natural_frequency_hz=FN_HZ)
    assert any("a dropout" in w and "22.00-22.50 s" in w for w in result["warnings"])
