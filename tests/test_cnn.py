"""CNN on canonical windows: invariances, end-to-end training, ONNX export and parity."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import onnx
import pytest
from test_progress import Recorder

from stiffnet import progress
from stiffnet.config import load_config, validate_config
from stiffnet.dataset.store import load_dataset
from stiffnet.errors import ConfigError, SignalError
from stiffnet.features.windows import (
    canonical_window,
    default_delays,
    embedded_channels,
    window_tensor,
)
from stiffnet.io_utils import sha256_file
from stiffnet.uncertainty.alarm import load_alarm
from training.config import TrainConfig
from training.families.cnn.config import CNNConfig

torch = pytest.importorskip("torch")

SMALL_CNN = {
    "periods": 8,
    "width": 8,
    "n_blocks": 2,
    "max_epochs": 3,
    "patience": 2,
    "batch_size": 32,
}


@pytest.fixture(scope="module")
def trained(tiny_dir, tmp_path_factory):
    from training.train import train

    torch.set_num_threads(1)
    work = tmp_path_factory.mktemp("cnnrun")
    uri = f"sqlite:///{work / 'mlflow.db'}"
    cfg = TrainConfig(model="cnn", experiment="test-cnn", cnn=SMALL_CNN)
    display = Recorder()
    with progress.reporting(display):
        summary = train(tiny_dir, cfg, work / "out", tracking_uri=uri, progress=None)
    summary["_progress"] = display
    return summary, uri, work


def test_onnx_export_prints_no_torchvision_warnings():
    """torch.onnx logs four "torchvision is not installed" lines on its first export."""
    code = (
        "from training.families.cnn.network import StiffnessCNN\n"
        "from training.families.cnn.export import _export_proto\n"
        "_export_proto(StiffnessCNN(3, 5, 8, 2), 3, 64)\n"
    )
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(root)})  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "torchvision" not in proc.stderr + proc.stdout


def test_training_reports_each_epoch_with_losses(trained):
    summary = trained[0]
    updates = [e for e in summary["_progress"].events if e[:2] == ("update", "training epochs")]
    assert [e[2] for e in updates] == list(range(1, len(updates) + 1))
    assert 1 <= len(updates) <= SMALL_CNN["max_epochs"]
    assert all("train loss" in e[3] and "val loss" in e[3] for e in updates)
    assert ("add", "training epochs", SMALL_CNN["max_epochs"]) in summary["_progress"].events


def _spiky(fs_ratio=97.3, periods=10, fn=9.48, seed=0):
    """Forced response plus one sharp upward spike per period, with noise."""
    fs = fs_ratio * fn
    t = np.arange(int(periods * fs_ratio)) / fs
    x = np.sin(2 * np.pi * fn * 0.9 * t)
    phase = (t * fn * 0.9) % 1.0
    x += 4.0 * np.exp(-(((phase - 0.3) / 0.02) ** 2))
    x += 0.05 * np.random.default_rng(seed).standard_normal(t.size)
    return x, fs, fn


def test_canonical_window_shape_and_invariances():
    x, fs, fn = _spiky()
    w = canonical_window(x, fs, fn, rate=32, periods=16)
    assert w.dtype == np.float32 and w.shape == (512,)
    n_valid = int((x.size - 1) / (97.3 / 32)) + 1  # canonical samples covered by the data
    valid = w[:n_valid]
    assert abs(valid.mean()) < 1e-5 and abs(valid.std() - 1.0) < 1e-4
    assert (w[n_valid:] == 0).all()  # zero-padded past the data
    assert valid.max() > -valid.min()  # spikes point up
    for gain in (1000.0, -1.0, -1000.0, 1e-3):
        np.testing.assert_allclose(canonical_window(gain * x, fs, fn), w, atol=1e-5)
    # a longer window is cropped to the requested number of periods
    assert canonical_window(x, fs, fn, rate=16, periods=4).shape == (64,)
    # the rate is the same whatever the input sampling rate
    x2, fs2, _ = _spiky(fs_ratio=311.0)
    w2 = canonical_window(x2, fs2, fn)
    assert np.corrcoef(w[:300], w2[:300])[0, 1] > 0.95


def _contract_window(x, fs, fn, rate, periods):
    """The preprocessing contract written step by step with the public science functions."""
    from scipy.signal import butter, sosfiltfilt

    from stiffnet.geometry.estimate import impact_polarity, smoothing_window
    from stiffnet.nlts.preprocess import detect_impacts, savgol_smooth

    a = (x - x.mean()) / x.std()
    p = fs / fn
    s = savgol_smooth(a, smoothing_window(p), 2)
    pol = impact_polarity(s, detect_impacts(s, min_separation=max(1, int(0.25 * p))))
    a = (pol or (1 if np.mean(a**3) >= 0 else -1)) * a
    ratio = p / rate
    if ratio > 1.1:
        a = sosfiltfilt(butter(8, 0.45 * 2 / ratio, output="sos"), a)
    c = np.interp(np.arange(int((a.size - 1) / ratio) + 1) * ratio, np.arange(a.size), a)
    n = rate * periods
    if c.size > n:
        c = c[(c.size - n) // 2 :][:n]
    out = np.zeros(n)
    out[: c.size] = (c - c.mean()) / (c - c.mean()).std()
    return out


@pytest.mark.parametrize(
    ("fs_ratio", "periods", "gain"), [(97.3, 10, 1.0), (311.0, 20, -2.5), (40.0, 20, 1.0)]
)
def test_canonical_windows_follow_the_written_contract(fs_ratio, periods, gain):
    """Batched implementation == the contract's steps (np.interp, detect_impacts), any rate."""
    x, fs, fn = _spiky(fs_ratio=fs_ratio, periods=periods)
    ref = _contract_window(gain * x, fs, fn, 32, 16)
    np.testing.assert_allclose(canonical_window(gain * x, fs, fn), ref, atol=2e-6)
    assert canonical_window(gain * x, fs, fn).max() > 3  # spikes point up after the flip


def test_canonical_window_errors():
    x, fs, fn = _spiky()
    with pytest.raises(ConfigError):
        canonical_window(x, fs, 0.0)
    with pytest.raises(ConfigError):
        canonical_window(x, -1.0, fn)
    with pytest.raises(SignalError):
        canonical_window(np.ones(100), fs, fn)


def test_embedded_channels():
    assert default_delays(32) == (0, 6, 12)
    w = np.arange(10, dtype=np.float32)
    e = embedded_channels(w, (0, 2, 4))
    assert e.shape == (3, 10) and e.dtype == np.float32
    np.testing.assert_array_equal(e[1, :8], w[2:])
    assert (e[2, 6:] == 0).all()
    assert embedded_channels(np.zeros(512)).shape == (3, 512)
    x, fs, fn = _spiky()
    X = window_tensor([x, -3 * x], fs, fn)
    assert X.shape == (2, 3, 512)
    np.testing.assert_allclose(X[0], X[1], atol=1e-5)


def test_windows_module_imports_no_heavy_libraries():
    code = (
        "import sys, stiffnet.features.windows\n"
        "bad = [m for m in ('torch', 'sklearn', 'mlflow') if m in sys.modules]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_cnn_yaml_restates_defaults():
    cfg = load_config(TrainConfig, "configs/train/cnn.yaml")
    assert cfg.model == "cnn" and cfg.cnn == CNNConfig()
    # the held-out fractions are the one deliberate change (models/README.md: 4,000 trajectories)
    assert (cfg.test_fraction, cfg.calibration_fraction) == (0.1, 0.1)
    restated = {"test_fraction": 0.2, "calibration_fraction": 0.2}
    assert cfg.model_copy(update=restated) == TrainConfig(model="cnn")
    assert cfg.experiment == cfg.registered_model == "stiffnet-cnn"
    with pytest.raises(ConfigError, match="width"):
        validate_config(TrainConfig, {"model": "cnn", "cnn": {"width": 0}})


def test_training_writes_onnx_with_card_and_metadata(trained, tiny_dir):
    summary, _, _ = trained
    path = summary["paths"]["onnx"]
    assert path.endswith("cnn.onnx")
    card = json.loads(open(summary["paths"]["card"]).read())
    assert card["sha256"] == sha256_file(path)
    assert card["model"] == "cnn"
    assert card["data"]["card_sha256"] == sha256_file(tiny_dir / "card.json")
    m = onnx.load(path)
    assert not any(t.data_location == onnx.TensorProto.EXTERNAL for t in m.graph.initializer)
    meta = {p.key: p.value for p in m.metadata_props}
    assert meta["model_kind"] == "stiffnet.cnn"
    ds = load_dataset(tiny_dir)
    assert json.loads(meta["class_names"]) == ds.class_names
    assert json.loads(meta["canonical_rate"]) == 32
    assert json.loads(meta["window_length"]) == 32 * 8
    assert json.loads(meta["delays"]) == [0, 6, 12]
    assert meta["training_data_sha256"] == sha256_file(tiny_dir / "card.json")
    assert float(meta["conformal_quantile"]) == pytest.approx(summary["conformal_quantile"])
    assert [i.name for i in m.graph.input] == ["windows"]
    assert [o.name for o in m.graph.output] == [
        "probabilities",
        "log_beta",
        "log_beta_scale",
        "embedding",
    ]
    # the recording-level interval and the alarm travel with the model, verified by hash
    q_rec = float(meta["conformal_quantile_recording"])
    # (infinite on the tiny set: too few calibration trajectories for 90 %)
    assert q_rec > 0 and q_rec == pytest.approx(summary["conformal_quantile_recording"])
    alarm = Path(path).with_name(meta["alarm_reference"])
    assert alarm.name == "cnn.alarm.npz" and meta["alarm_sha256"] == sha256_file(alarm)
    assert card["data"]["priors"]["sweep"]["beta"] == list(ds.card["config"]["sweep"]["beta"])
    assert set(load_alarm(alarm).thresholds) <= {
        "embedding", "ambiguity", "beta_uncertainty", "class_edge"}  # fmt: skip
    metrics = summary["metrics"]
    for prefix in ("", "geometric/"):
        assert 0.0 <= metrics[f"{prefix}accuracy"] <= 1.0
        assert f"{prefix}macro_f1" in metrics
    assert "beta_mape" in metrics and "beta_coverage" in metrics
    # self-describing: the training rig's f_n and the class edges travel in the metadata
    assert json.loads(meta["natural_frequency_hz"]) == card["data"]["natural_frequency_hz"]
    edges = [c["beta"][0] for c in ds.card["config"]["classes"]]
    assert json.loads(meta["class_edges"])[:-1] == edges


def test_onnx_parity_and_dynamic_batch(trained, tiny_dir):
    from training.families.cnn.export import export_cnn_onnx, onnx_predict_cnn, parity_cnn
    from training.families.cnn.network import StiffnessCNN, predict_cnn

    summary, _, _ = trained
    assert summary["parity"]["max_abs_proba_diff"] < 1e-4
    assert summary["parity"]["label_agreement"] == 1.0
    ds = load_dataset(tiny_dir)
    X = window_tensor(
        ds.windows()[:5], ds.column("fs_hz")[:5], ds.column("natural_frequency_hz")[:5], 32, 8
    )
    for n in (1, 5):
        out = onnx_predict_cnn(summary["paths"]["onnx"], X[:n])
        assert out["probabilities"].shape == (n, len(ds.class_names))
        np.testing.assert_allclose(out["probabilities"].sum(axis=1), 1.0, atol=1e-5)
    # parity of a directly exported network on real canonical windows
    torch.manual_seed(0)
    net = StiffnessCNN(3, len(ds.class_names), 8, 2, 7, 0.1, 3.0, 0.7).eval()
    path = Path(summary["paths"]["onnx"]).parent / "direct.onnx"
    export_cnn_onnx(
        net,
        ds.class_names,
        path,
        rate=32,
        periods=8,
        delays=[0, 6, 12],
        delay_fraction=0.18,
        metadata={"conformal_quantile": 0.1},
        card={},
    )
    out = onnx_predict_cnn(path, X)
    p, lb = predict_cnn(net, X)
    assert np.max(np.abs(out["probabilities"] - p)) < 1e-4
    assert np.max(np.abs(out["log_beta"] - lb)) < 1e-4
    assert parity_cnn(path, net, X)["max_abs_proba_diff"] < 1e-4


def test_mlflow_run_has_cnn_metrics(trained):
    import mlflow

    summary, uri, _ = trained
    run = mlflow.MlflowClient(uri).get_run(summary["run_id"])
    # the same metric names as every family's, the family a parameter and a tag
    assert "accuracy" in run.data.metrics and "geometric/accuracy" in run.data.metrics
    assert run.data.params["family"] == "cnn" and run.data.tags["stiffnet.family"] == "cnn"


def test_mlflow_logs_epoch_losses_and_the_model(trained):
    import mlflow
    import onnxruntime as ort

    summary, uri, _ = trained
    client = mlflow.MlflowClient(uri)
    run_id = summary["run_id"]
    path = Path(summary["paths"]["onnx"])
    card = json.loads(path.with_suffix(".card.json").read_text())
    history = card["training"]["history"]
    for key in ("train_loss", "val_loss"):
        points = client.get_metric_history(run_id, key)
        assert [p.step for p in sorted(points, key=lambda p: p.step)] == [
            h["epoch"] for h in history
        ]
        assert [p.value for p in sorted(points, key=lambda p: p.step)] == pytest.approx(
            [h[key] for h in history]
        )
    run = client.get_run(run_id)
    models = client.search_logged_models(experiment_ids=[run.info.experiment_id])
    mine = [m for m in models if m.source_run_id == run_id]
    assert len(mine) == 1 and mine[0].name == "model"
    model = mine[0]
    assert model.metrics and {m.key for m in model.metrics} >= {"accuracy"}
    onnx_model = mlflow.onnx.load_model(f"models:/{model.model_id}")
    info = mlflow.models.get_model_info(f"models:/{model.model_id}")
    sig = info.signature.inputs.to_dict()[0]
    sess = ort.InferenceSession(str(path))
    logged = ort.InferenceSession(onnx_model.SerializeToString())
    inp = sess.get_inputs()[0]
    x = np.random.default_rng(0).standard_normal((3, *inp.shape[1:])).astype(np.float32)
    for a, b in zip(sess.run(None, {inp.name: x}), logged.run(None, {inp.name: x}), strict=True):
        np.testing.assert_array_equal(a, b)  # the logged model is the exported one
    assert list(sig["tensor-spec"]["shape"][1:]) == list(sess.get_inputs()[0].shape[1:])
    assert info.metadata["stiffnet_card"]["sha256"] == card["sha256"]
