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
