"""The shipped CNN describes its own input: a plain-onnxruntime script reproduces the predictor."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _example() -> str:
    text = (ROOT / "docs" / "serving.md").read_text(encoding="utf-8")
    block = text.split("<!-- plain-onnxruntime-example -->", 1)[1]
    return re.search(r"```python\n(.*?)```", block, re.S).group(1)


def test_metadata_holds_the_preprocessing_contract():
    import onnxruntime as ort

    sess = ort.InferenceSession(str(ROOT / "models" / "cnn.onnx"))
    meta = sess.get_modelmeta().custom_metadata_map
    contract = json.loads(meta["preprocessing"])
    steps = " ".join(contract["steps"])
    for needle in ("butter(8", "sosfiltfilt", "numpy.interp", "Savitzky-Golay", "mean(a**3)"):
        assert needle in steps
    assert contract["canonical_rate"] == json.loads(meta["canonical_rate"])
    assert contract["delays"] == json.loads(meta["delays"])


def test_plain_onnxruntime_example_reproduces_the_predictor():
    from serving.predictor import predict_recording

    run = subprocess.run(
        [sys.executable, "-c", _example()], cwd=ROOT, capture_output=True, text=True, check=True
    )
    cls, beta = run.stdout.split()
    want = predict_recording(ROOT / "examples" / "recordings" / "impact_beta45.csv")
    assert cls == want["class"]
    assert float(beta) == pytest.approx(want["beta"], rel=1e-4)
    # no stiffnet import in the example: only onnxruntime, numpy, scipy
    assert "stiffnet" not in _example() and "serving" not in _example()


@pytest.mark.parametrize("name", ["cnn", "gbm"])
def test_shipped_models_say_their_rig_and_classes(name):
    """f_n of the training rig and the class edges travel in both families' metadata."""
    import onnxruntime as ort

    from stiffnet.uncertainty.alarm import load_alarm

    meta = ort.InferenceSession(str(ROOT / "models" / f"{name}.onnx")).get_modelmeta()
    meta = meta.custom_metadata_map
    card = json.loads((ROOT / "models" / f"{name}.card.json").read_text())
    assert json.loads(meta["natural_frequency_hz"]) == card["data"]["natural_frequency_hz"] > 0
    edges = json.loads(meta["class_edges"])
    assert edges == load_alarm(ROOT / "models" / f"{name}.alarm.npz").info["class_edges"]
    assert edges == sorted(edges) and len(edges) == len(json.loads(meta["class_names"]))


def test_gbm_metadata_holds_its_feature_contract():
    """The GBM's input is reproducible from its metadata: features, their version, the cut."""
    import onnxruntime as ort

    from stiffnet.features import FEATURE_NAMES, FEATURE_VERSION

    meta = ort.InferenceSession(str(ROOT / "models" / "gbm.onnx")).get_modelmeta()
    meta = meta.custom_metadata_map
    contract = json.loads(meta["feature_contract"])
    assert json.loads(meta["feature_names"]) == FEATURE_NAMES
    assert contract["feature_version"] == json.loads(meta["feature_version"]) == FEATURE_VERSION
    assert contract["cut"]["window_periods"] == json.loads(meta["window_periods"]) == 16
    assert "round(window_periods * fs / f_n)" in contract["cut"]["window_samples"]
    assert "inclination_features" in contract["features"]
