"""The ONNX predictor: parity with training, invariances, f_n resolution, OOD, integrity."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from serving.predictor import Predictor, predict_recording
from stiffnet.errors import StiffnetError
from stiffnet.features.windows import window_length, window_tensor
from stiffnet.recordings import read_recording, write_recording_csv
from stiffnet.uncertainty.alarm_verdict import (
    class_beta_gap,
    restoring_force_gap,
    weak_restoring_force_fit,
    with_class_beta_check,
    with_restoring_force_check,
)

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "recordings"
EXAMPLE_FILES = sorted(EXAMPLES.glob("impact_*.csv"))
EXAMPLE = EXAMPLES / "impact_beta45.csv"
#: The examples' natural frequency (their sidecars say so).
FN = 9.48


@pytest.fixture(scope="module")
def cnn():
    return Predictor.load()


@pytest.fixture(scope="module")
def gbm():
    return Predictor.load(ROOT / "models" / "gbm.onnx")


@pytest.fixture(scope="module")
def example():
    return read_recording(EXAMPLE)


@pytest.fixture(scope="module")
def dataset_windows(tmp_path_factory):
    """Eight windows simulated by the training data's generator on the default domain."""
    import pyarrow.parquet as pq

    from stiffnet.config import load_yaml, validate_config
    from stiffnet.config.sim import SimulationConfig
    from stiffnet.dataset.generate import generate_dataset

    data = load_yaml(ROOT / "configs" / "sim" / "ideal.yaml")
    data.update(seed=11, n_trajectories=4, shard_size=4)
    data["windows"]["per_trajectory"] = 2
    out = tmp_path_factory.mktemp("serving") / "ds"
    generate_dataset(validate_config(SimulationConfig, data), out)
    t = pq.read_table(sorted((out / "shards").glob("*.parquet"))[0])
    return (
        [np.asarray(a, dtype=np.float64) for a in t.column("accel").to_pylist()],
        t.column("fs_hz").to_numpy(),
        t.column("natural_frequency_hz").to_numpy(),
    )


def test_examples_are_predicted_right_and_use_their_sidecar(cnn):
    assert EXAMPLE_FILES, "examples/recordings must ship recordings"
    for path in EXAMPLE_FILES:
        side = json.loads(Path(str(path) + ".json").read_text())
        r = predict_recording(path, predictor=cnn)
        assert r["class"] == side["provenance"]["true_class"], path
        lo, hi = r["beta_interval"]
        assert lo < r["beta"] < hi
        assert r["natural_frequency_source"].startswith("sidecar:")
        assert r["natural_frequency_hz"] == side["natural_frequency_hz"]
        assert path.stat().st_size < 600_000
        json.dumps(r)  # JSON-serialisable as is


def test_output_fields(cnn, example):
    r = cnn.predict(example.accel, example.fs_hz, source="x", natural_frequency_hz=FN)
    for key in (
        "class",
        "probabilities",
        "beta",
        "beta_interval",
        "geometric",
        "agreement",
        "contact_detected",
        "ood_score",
        "ood_flag",
        "n_windows",
        "segments",
        "model",
        "natural_frequency_hz",
        "natural_frequency_source",
        "warnings",
    ):
        assert key in r
    assert set(r["geometric"]) >= {
        "class",
        "beta",
        "inclination_before_deg",
        "inclination_after_deg",
    }
    assert r["model"] == {"name": "cnn", "sha256": cnn.sha256, "kind": "cnn"}
    assert abs(sum(r["probabilities"].values()) - 1) < 1e-5
    # the log's sliding windows (hop 0.5 s), read once for the estimate and the layers
    assert r["hop_s"] == pytest.approx(0.5)
    assert r["n_windows"] == int((example.duration_s - r["window_s"]) // r["hop_s"]) + 1
    assert r["layers"][0]["n_points"] == r["n_windows"]
    assert r["layers"][0]["beta"] == pytest.approx(r["beta"])  # one layer: the same windows
    assert r["natural_frequency_source"] == "argument"
    assert r["natural_frequency_hz"] == pytest.approx(9.48)
    assert r["layers"] and len(r["layers"]) == 1 and "layers" not in r["alarm"]["fired"]
    assert r["agreement"] == (r["geometric"]["class"] == r["class"])
    assert r["contact_detected"] and not r["ood_flag"]


def test_no_silent_natural_frequency(cnn, example, tmp_path):
    """Without f_n (option, sidecar, manifest) the predictor refuses: never the training data's."""
    with pytest.raises(StiffnetError, match="natural frequency unknown.*not assumed"):
        cnn.predict(example.accel, example.fs_hz)
    rec = write_recording_csv(tmp_path / "r.csv", example.accel, example.fs_hz)
    with pytest.raises(StiffnetError, match=r"r\.csv: natural frequency unknown"):
        predict_recording(rec, predictor=cnn)


def test_restoring_force_cross_check_fields(cnn):
    """The restoring-force estimate beside the model: beta of the examples, agreement, refusal."""
    for path in EXAMPLE_FILES:
        side = json.loads(Path(str(path) + ".json").read_text())
        r = predict_recording(path, predictor=cnn)
        true_beta = side["provenance"]["true_beta"]
        assert (
            r["restoring_force_class"]
            == side["provenance"]["true_class"]
            == r["restoring_force"]["class"]
        )
        assert r["restoring_force_beta"] == pytest.approx(true_beta, rel=0.1)
        lo, hi = r["restoring_force_beta_interval"]
        assert lo <= r["restoring_force_beta"] <= hi
        assert r["restoring_force_agreement"] == (r["restoring_force_class"] == r["class"])
    # a recording without contact: the cross-check refuses with its reason, no error
    t = np.arange(20000) / 2000.0
    free = np.sin(2 * np.pi * 9.9 * t) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    r = cnn.predict(free, 2000.0, natural_frequency_hz=FN)
    assert r["restoring_force_beta"] is None and r["restoring_force"]["reason"]
    assert r["restoring_force_agreement"] in (None, r["restoring_force_class"] == r["class"])


def test_restoring_force_gap_is_the_log_gap_between_disjoint_intervals():
    assert restoring_force_gap([10.0, 20.0], [15.0, 40.0]) == 0.0  # overlapping
    assert restoring_force_gap([10.0, 20.0], [20.0, 40.0]) == 0.0  # touching
    assert restoring_force_gap([10.0, 20.0], [40.0, 80.0]) == pytest.approx(np.log(2.0))
    assert restoring_force_gap([40.0, 80.0], [10.0, 20.0]) == pytest.approx(np.log(2.0))
    assert (
        restoring_force_gap(None, [1.0, 2.0]) is None
        and restoring_force_gap([1.0, 2.0], None) is None
    )
    # a poor contact-law fit contradicts nothing; a good one does
    assert restoring_force_gap([10.0, 20.0], [40.0, 80.0], contact_r2=0.8) is None
    assert restoring_force_gap([10.0, 20.0], [40.0, 80.0], contact_r2=0.99) == pytest.approx(
        np.log(2.0)
    )


def test_restoring_force_check_joins_the_alarm():
    quiet = {
        "flag": False,
        "fired": [],
        "scores": {"embedding": 0.5},
        "thresholds": {"embedding": 1.0},
    }
    assert (
        with_restoring_force_check(quiet, None) is quiet
    )  # the cross-check refused: nothing to say
    agree = with_restoring_force_check(quiet, 0.0)
    assert not agree["flag"] and agree["scores"]["restoring_force"] == 0.0
    clash = with_restoring_force_check(quiet, 0.7)
    assert (
        clash["flag"]
        and clash["fired"] == ["restoring_force"]
        and "restoring-force" in clash["message"]
    )
    assert (
        quiet["fired"] == [] and "restoring_force" not in quiet["scores"]
    )  # the input is not changed
    alone = with_restoring_force_check(None, 0.7)  # a model without an alarm reference
    assert alone["flag"] and alone["fired"] == ["restoring_force"]


NAMES = ["no_contact", "soft", "medium", "hard", "very_hard"]
EDGES = [5.0, 15.0, 35.0, 60.0, 100.0]


def test_class_beta_gap_is_the_log_gap_between_the_interval_and_the_class_range():
    assert class_beta_gap("hard", [50.0, 70.0], NAMES, EDGES) == 0.0  # overlaps 35-60
    assert class_beta_gap("hard", [64.0, 78.0], NAMES, EDGES) == pytest.approx(np.log(64 / 60))
    assert class_beta_gap("medium", [5.0, 14.0], NAMES, EDGES) == pytest.approx(np.log(15 / 14))
    # the outer classes are open-ended: beyond the training range is another check's business
    assert class_beta_gap("soft", [1.0, 3.0], NAMES, EDGES) == 0.0
    assert class_beta_gap("very_hard", [200.0, 300.0], NAMES, EDGES) == 0.0
    assert class_beta_gap("soft", [40.0, 50.0], NAMES, EDGES) == pytest.approx(np.log(40 / 15))
    # nothing to compare: no contact, no interval, edges that do not fit the classes
    assert class_beta_gap("no_contact", [1.0, 2.0], NAMES, EDGES) is None
    assert class_beta_gap("hard", None, NAMES, EDGES) is None
    assert class_beta_gap("hard", [64.0, 78.0], NAMES, EDGES[:-1]) is None


def test_a_class_its_own_beta_contradicts_fires_the_alarm():
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    clash = with_class_beta_check(quiet, class_beta_gap("hard", [64.0, 78.0], NAMES, EDGES))
    assert clash["flag"] and clash["fired"] == ["class_beta"]
    assert "class and its own beta disagree" in clash["message"]
    fine = with_class_beta_check(quiet, class_beta_gap("hard", [50.0, 70.0], NAMES, EDGES))
    assert not fine["flag"] and fine["scores"]["class_beta"] == 0.0


def test_the_shipped_models_class_and_beta_agree_on_the_examples(cnn):
    """Each example's class contains its beta interval's reading: no class_beta alarm."""
    for path in EXAMPLE_FILES:
        rec = read_recording(path)
        r = cnn.predict(rec.accel, rec.fs_hz, natural_frequency_hz=FN)
        assert r["alarm"]["scores"]["class_beta"] == 0.0, path.name


def test_a_poor_contact_law_fit_is_called_weak_evidence():
    assert weak_restoring_force_fit({"beta": 30.0, "contact_r2": 0.99}) is None
    assert (
        weak_restoring_force_fit({"beta": None, "contact_r2": 0.5}) is None
    )  # refused: said already
    words = weak_restoring_force_fit({"beta": 30.0, "contact_r2": 0.93})
    assert "93 %" in words and "weak evidence" in words


def test_a_contradicting_cross_check_raises_the_alarm(cnn, example, monkeypatch):
    """Two physical readings of beta that cannot both be right: the user is warned."""
    import serving.predictor as predictor_module

    accel, fs = example.accel, example.fs_hz
    r = cnn.predict(accel, fs, natural_frequency_hz=FN)
    assert not r["ood_flag"] and r["alarm"]["scores"]["restoring_force"] == 0.0
    lo, hi = r["beta_interval"]

    def far(*args, **kwargs):
        beta = 3.0 * hi
        return {
            "class": "hard",
            "beta": beta,
            "beta_interval": [0.9 * beta, 1.1 * beta],
            "contact_r2": 0.99,
            "reason": "a contradicting reading (test)",
        }

    monkeypatch.setattr(predictor_module, "restoring_force_check", far)
    r = cnn.predict(accel, fs, natural_frequency_hz=FN)
    assert r["ood_flag"] and "restoring_force" in r["alarm"]["fired"]
    assert r["alarm"]["scores"]["restoring_force"] == pytest.approx(np.log(2.7 * hi / hi))
    assert any("restoring-force" in w for w in r["warnings"])
    assert r["class"] == "hard"  # the model's answer stands; it now carries the warning


@pytest.mark.parametrize("gain", [1e3, 1e-3, -1.0, -1e3, 1e300, -1e-300])
def test_gain_and_polarity_invariance(cnn, example, gain):
    ref = cnn.predict(example.accel, example.fs_hz, natural_frequency_hz=FN)
    r = cnn.predict(gain * example.accel, example.fs_hz, natural_frequency_hz=FN)
    assert r["class"] == ref["class"]
    for k, p in ref["probabilities"].items():
        assert abs(r["probabilities"][k] - p) < 1e-5
    assert r["beta"] == pytest.approx(ref["beta"], rel=1e-5)
    assert r["geometric"]["class"] == ref["geometric"]["class"]
    assert r["ood_score"] == pytest.approx(ref["ood_score"], rel=1e-4)


def test_batched_canonical_windows_equal_one_at_a_time(dataset_windows, example):
    """A recording's windows in one batch == the training path, window by window."""
    wins, fs, fn = dataset_windows
    for w, f, n in zip(wins, fs, fn, strict=True):
        batched = window_tensor(np.asarray(w)[None, :], f, n, 32, 16, (0, 6, 12))
        assert np.array_equal(batched, window_tensor([w], f, n, 32, 16, (0, 6, 12)))
    n = window_length(example.fs_hz, 9.48, 16)
    W = example.accel[: 4 * n].reshape(4, n)
    assert np.array_equal(
        window_tensor(W, example.fs_hz, 9.48), window_tensor(list(W), example.fs_hz, 9.48)
    )


def test_parity_with_the_training_onnx_path(cnn, gbm, dataset_windows):
    """One dataset window through the predictor == the training code's ONNX call."""
    from stiffnet.features import feature_matrix
    from training.families.cnn.export import onnx_predict_cnn
    from training.families.gbm.export import onnx_predict

    wins, fs, fn = dataset_windows
    X = window_tensor(wins, fs, fn, 32, 16, (0, 6, 12))
    ref = onnx_predict_cnn(cnn.model.path, X)
    ref_gbm = onnx_predict(gbm.model.path, feature_matrix(wins, fs, fn))
    for i, (w, f, n) in enumerate(zip(wins, fs, fn, strict=True)):
        assert window_length(f, n, 16) == w.size  # the dataset's windowing rule
        r = cnn.predict(w, f, natural_frequency_hz=n)
        assert r["n_windows"] == 1
        np.testing.assert_allclose(
            list(r["probabilities"].values()), ref["probabilities"][i], atol=1e-6
        )
        if r["beta"] is not None:
            assert r["beta"] == pytest.approx(ref["beta"][i], rel=1e-5)
        rg = gbm.predict(w, f, natural_frequency_hz=n)
        np.testing.assert_allclose(
            list(rg["probabilities"].values()), ref_gbm["probabilities"][i], atol=1e-6
        )


def test_natural_frequency_resolution(cnn, example, tmp_path):
    rec = tmp_path / "r.csv"
    shutil.copy(EXAMPLE, rec)
    with pytest.raises(StiffnetError, match="natural frequency unknown"):
        predict_recording(rec, predictor=cnn)  # no option, no sidecar: refused
    Path(str(rec) + ".json").write_text(json.dumps({"natural_frequency_hz": 9.5}))
    r = predict_recording(rec, predictor=cnn)
    assert r["natural_frequency_source"] == f"sidecar:{rec}.json"
    assert r["natural_frequency_hz"] == 9.5
    r = predict_recording(rec, predictor=cnn, natural_frequency_hz=9.4)
    assert (r["natural_frequency_source"], r["natural_frequency_hz"]) == ("argument", 9.4)
    Path(str(rec) + ".json").write_text("{oops")
    with pytest.raises(StiffnetError, match="sidecar"):
        predict_recording(rec, predictor=cnn)


def test_a_record_with_layers_says_so_instead_of_a_silent_blend(cnn):
    a = [read_recording(p) for p in EXAMPLE_FILES]  # soft (beta 12), then hard (beta 45)
    x = np.concatenate([r.accel for r in a])
    r = cnn.predict(x, a[0].fs_hz, natural_frequency_hz=FN)
    classes = [s["class"] for s in r["segments"]]
    assert classes[0] == "soft" and classes[-1] == "hard"
    layers = r["layers"]
    assert [la["class"] for la in layers] == ["soft", "hard"]
    assert abs(layers[1]["start_s"] - a[0].duration_s) <= 1.0
    assert layers[0]["beta"] == pytest.approx(12, rel=0.15)
    assert layers[1]["beta"] == pytest.approx(45, rel=0.15)
    assert r["ood_flag"] and "layers" in r["alarm"]["fired"]
    assert "beta changes along this record" in r["alarm"]["message"]
    assert any("beta changes along this record" in w for w in r["warnings"])
    assert r["segments"][-1]["end_s"] <= r["duration_s"]


def _ood(p: Predictor, x: np.ndarray, fs: float = 1000.0) -> float:
    return p.predict(x, fs, natural_frequency_hz=FN)["ood_score"]


def test_ood_score_rises_off_distribution(cnn, example):
    rng = np.random.default_rng(0)
    t = np.arange(example.accel.size) / example.fs_hz
    base = _ood(cnn, example.accel)
    noise = cnn.predict(rng.standard_normal(t.size), 1000.0, natural_frequency_hz=FN)
    assert noise["ood_score"] > 3 * base and noise["ood_flag"]
    sine = _ood(cnn, np.sin(2 * np.pi * 31.0 * t))  # no impacts, 3.3 x f_n
    assert sine > 3 * base
    distorted = np.tanh(50 * example.accel / np.abs(example.accel).max())  # saturated amplifier
    assert _ood(cnn, distorted) > base
    assert not cnn.predict(example.accel, 1000.0, natural_frequency_hz=FN)["ood_flag"]


def test_bad_signals(cnn, example):
    fs = example.fs_hz
    with pytest.raises(StiffnetError, match="too short.*needs 1.69 s"):
        cnn.predict(example.accel[:1000], fs, natural_frequency_hz=FN)
    with pytest.raises(StiffnetError, match="constant"):
        cnn.predict(np.full(5000, 3.0), fs, natural_frequency_hz=FN)
    with pytest.raises(StiffnetError, match="below the minimum 474 Hz") as info:
        cnn.predict(example.accel[::3], fs / 3, natural_frequency_hz=FN)
    assert "time unit" not in str(info.value)  # 333 Hz: simply too low
    fn_words = "if the natural frequency is not 9.48 Hz, give it (--fn: this rate reads one up to"
    assert f"{fn_words} 6.67 Hz)" in str(info.value)
    # a mistyped f_n (2500 Hz for the rig's 25) is named beside the unit story
    with pytest.raises(StiffnetError, match=r"natural frequency is not 2500 Hz.*up to 20 Hz"):
        cnn.predict(example.accel, fs, natural_frequency_hz=2500.0)
    # times in milliseconds read as seconds: 1 Hz, and the message names the fix
    with pytest.raises(StiffnetError, match=r"in milliseconds.*--time-unit ms.*1000 Hz"):
        cnn.predict(example.accel, fs / 1000, natural_frequency_hz=FN)
    for fs_bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(StiffnetError, match="fs_hz"):
            cnn.predict(example.accel, fs_bad, natural_frequency_hz=FN)
    with pytest.raises(StiffnetError, match="natural_frequency_hz"):
        cnn.predict(example.accel, fs, natural_frequency_hz=-2)
    bad = example.accel.copy()
    bad[7] = np.nan
    with pytest.raises(StiffnetError, match="NaN/inf"):
        cnn.predict(bad, fs, natural_frequency_hz=FN)
    for x in ([], [1.0]):
        with pytest.raises(StiffnetError, match="empty|one sample"):
            cnn.predict(np.array(x), fs, natural_frequency_hz=FN)
    with pytest.raises(StiffnetError, match="1-D"):
        cnn.predict(np.ones((3, 3)), fs, natural_frequency_hz=FN)
    for fs_x, fn_x in ((1e308, 1e-308), (1e3, 1e-300), (1e300, 1.0)):  # overflowing windows
        with pytest.raises(StiffnetError, match=r"must be in \["):  # physical ranges first
            cnn.predict(example.accel, fs_x, natural_frequency_hz=fn_x)
    with pytest.raises(StiffnetError, match=r"1e\+06 x the natural frequency"):
        cnn.predict(example.accel, 1e6, natural_frequency_hz=1.0)  # fs/f_n over 1e5
    with pytest.raises(StiffnetError, match=r"\(1688 samples at 1000 Hz\)"):
        cnn.predict(example.accel[:1000], fs, natural_frequency_hz=FN)


def test_clipped_signal_warns(cnn, example):
    lim = 0.3 * np.abs(example.accel).max()
    r = cnn.predict(np.clip(example.accel, -lim, lim), example.fs_hz, natural_frequency_hz=FN)
    assert any("clipped" in w for w in r["warnings"])


def test_model_integrity(tmp_path):
    src = ROOT / "models"
    shutil.copy(src / "cnn.onnx", tmp_path / "cnn.onnx")
    card = json.loads((src / "cnn.card.json").read_text())
    card["sha256"] = "0" * 64
    (tmp_path / "cnn.card.json").write_text(json.dumps(card))
    with pytest.raises(StiffnetError, match="does not match its card") as exc:
        Predictor.load(tmp_path / "cnn.onnx")
    assert "\n" not in str(exc.value)
    # corrupt file whose card was updated to match: ONNX Runtime refuses it cleanly
    from stiffnet.io_utils import sha256_file

    (tmp_path / "cnn.onnx").write_bytes(b"\x08\x07garbage" * 100)
    card["sha256"] = sha256_file(tmp_path / "cnn.onnx")
    (tmp_path / "cnn.card.json").write_text(json.dumps(card))
    with pytest.raises(StiffnetError, match="not a loadable ONNX model") as exc:
        Predictor.load(tmp_path / "cnn.onnx")
    assert "\n" not in str(exc.value)
    (tmp_path / "cnn.card.json").unlink()
    with pytest.raises(StiffnetError, match="model card"):
        Predictor.load(tmp_path / "cnn.onnx")
    with pytest.raises(StiffnetError, match="not found"):
        Predictor.load(tmp_path / "nope.onnx")


def test_sessions_use_explicit_threads(cnn):
    opts = cnn.model.session.get_session_options()
    assert (opts.intra_op_num_threads, opts.inter_op_num_threads) == (1, 1)


def test_gbm_predicts_the_example(gbm):
    r = predict_recording(EXAMPLE, predictor=gbm)
    assert r["class"] == "hard" and r["model"]["kind"] == "gbm"
    assert r["geometric"]["n_windows"] == r["n_windows"]  # all windows have features


def test_no_heavy_imports(tmp_path):
    """The CLI's predict path and the HTTP app never import torch, scikit-learn or mlflow."""
    npy = tmp_path / "r.npy"
    np.save(npy, read_recording(EXAMPLE).accel)
    code = f"""
import sys
from typer.testing import CliRunner
from stiffnet.cli import app
res = CliRunner().invoke(app, ["predict", {str(EXAMPLE)!r}])
assert res.exit_code == 0, res.output
res = CliRunner().invoke(app, ["predict", {str(npy)!r}, "--fs", "1000", "--fn", "9.48"])
assert res.exit_code == 0, res.output
import serving.app, serving.predictor
from fastapi.testclient import TestClient
client = TestClient(serving.app.create_app(serving.predictor.Predictor.load()))
assert client.get("/health").status_code == 200
heavy = sorted(m for m in sys.modules if m.split(".")[0] in ("torch", "sklearn", "mlflow"))
assert not heavy, heavy
print("ok")
"""
    out = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().endswith("ok")


def test_csv_written_recording_round_trip(cnn, example, tmp_path):
    p = write_recording_csv(tmp_path / "copy.csv", example.accel, example.fs_hz)
    r = predict_recording(p, predictor=cnn, natural_frequency_hz=9.48)
    assert r["class"] == "hard"


@settings(max_examples=50, deadline=None)
@given(
    fs=st.one_of(st.floats(), st.sampled_from([500.0, 1000.0, 3000.0])),
    fn=st.one_of(st.none(), st.floats(), st.sampled_from([9.48, 5.0, 20.0])),
    n=st.integers(0, 4000),
    seed=st.integers(0, 99),
    scale=st.sampled_from([0.0, 1e-300, 1.0, 1e300]),
)
def test_predict_only_raises_stiffnet_errors(cnn, fs, fn, n, seed, scale):
    """Random rates, natural frequencies, lengths and scales: a result or a one-line error."""
    x = scale * np.random.default_rng(seed).standard_normal(n)
    try:
        r = cnn.predict(x, fs, natural_frequency_hz=fn)
    except StiffnetError as exc:
        assert "\n" not in str(exc)
    else:
        json.dumps(r, allow_nan=False)


def test_parity_on_example_windows(cnn, example):
    """The same check on the shipped example (runs on a fresh clone without data/default)."""
    from training.families.cnn.export import onnx_predict_cnn

    n = window_length(example.fs_hz, 9.48, 16)
    wins = [example.accel[i * n : (i + 1) * n] for i in range(3)]
    ref = onnx_predict_cnn(cnn.model.path, window_tensor(wins, example.fs_hz, 9.48))
    for i, w in enumerate(wins):
        r = cnn.predict(w, example.fs_hz, natural_frequency_hz=9.48)
        np.testing.assert_allclose(
            list(r["probabilities"].values()), ref["probabilities"][i], atol=1e-6
        )
        assert r["beta"] == pytest.approx(ref["beta"][i], rel=1e-5)


def test_metadata_hash_of_digits_stays_a_string():
    # a training-data hash made only of digits must not decode to a number
    from serving.model import decode_metadata_value

    assert decode_metadata_value("training_data_sha256", "1234") == "1234"
    assert decode_metadata_value("window_length", "512") == 512
    assert decode_metadata_value("class_names", '["a", "b"]') == ["a", "b"]


def _model_copy(tmp_path: Path, edit) -> Path:
    """A copy of the shipped CNN whose ONNX metadata and card `edit(meta, card)` changed,
    re-hashed so that only the edit can make the loader refuse it."""
    import onnx

    from stiffnet.io_utils import sha256_file

    m = onnx.load(ROOT / "models" / "cnn.onnx")
    meta = {p.key: p.value for p in m.metadata_props}
    card = json.loads((ROOT / "models" / "cnn.card.json").read_text())
    edit(meta, card)
    del m.metadata_props[:]
    for k, v in meta.items():
        m.metadata_props.add(key=k, value=v)
    path = tmp_path / "cnn.onnx"
    onnx.save(m, path)
    card["sha256"] = sha256_file(path)
    path.with_suffix(".card.json").write_text(json.dumps(card))
    shutil.copy(ROOT / "models" / "cnn.alarm.npz", tmp_path / "cnn.alarm.npz")
    return path


def test_deeply_nested_model_metadata_is_refused_in_one_line(tmp_path):
    """In the library (HTTP and Python users too), not only by the CLI's catch-all."""
    from serving.model import decode_metadata_value

    deep = "[" * 100_000 + "]" * 100_000
    with pytest.raises(StiffnetError, match=r"metadata 'extra' is nested deeper than 64 levels"):
        decode_metadata_value("extra", deep)
    assert decode_metadata_value("extra", "[" * 64 + "]" * 64) is not None  # at the bound
    path = _model_copy(tmp_path, lambda meta, card: meta.update(extra=deep))
    with pytest.raises(StiffnetError, match=r"cnn\.onnx: metadata 'extra' is nested deeper"):
        Predictor.load(path)
    (tmp_path / "huge").mkdir()
    huge = _model_copy(tmp_path / "huge", lambda meta, card: meta.update(extra="x" * 17_000_000))
    with pytest.raises(StiffnetError, match="metadata is larger than 16 MB"):
        Predictor.load(huge)


def test_a_card_pointing_at_a_nested_json_is_passed_over(tmp_path, example):
    """The training f_n is looked up in the data card the model card names: a deeply nested
    one is read bounded (no RecursionError) and passed over like a missing one."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "card.json").write_text("[" * 100_000 + "]" * 100_000)

    def edit(meta, card):
        meta.pop("natural_frequency_hz")
        card["metadata"].pop("natural_frequency_hz", None)
        card["data"].pop("natural_frequency_hz", None)
        card["data"]["path"] = str(data)

    p = Predictor.load(_model_copy(tmp_path, edit), ood_reference=None)
    assert p.training_natural_frequency is None or p.training_natural_frequency_from != str(
        data / "card.json"
    )
    assert p.predict(example.accel, example.fs_hz, natural_frequency_hz=FN)["class"] == "hard"


def test_one_model_pass_gives_the_logs_layers(cnn, monkeypatch):
    """predict runs the model once over the log's windows; its layers are stiffnet log's."""
    from serving.log import stiffness_log

    a = [read_recording(p) for p in EXAMPLE_FILES]  # soft (beta 12), then hard (beta 45)
    x = np.concatenate([r.accel for r in a])
    log = stiffness_log(cnn, x, a[0].fs_hz, FN, restoring_force_every_s=None)
    calls = []
    run = Predictor._run_model
    monkeypatch.setattr(Predictor, "_run_model", lambda *p, **k: calls.append(1) or run(*p, **k))
    r = cnn.predict(x, a[0].fs_hz, natural_frequency_hz=FN)
    assert len(calls) == 1 and r["n_windows"] == log["n_points"]
    assert len(r["layers"]) == len(log["layers"]) == 2
    for mine, theirs in zip(r["layers"], log["layers"], strict=True):
        assert mine == {k: theirs[k] for k in mine}
