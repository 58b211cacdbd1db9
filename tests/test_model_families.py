"""Model families are plugins: a toy family from a test folder, through the registry only.

``tests/toy_family`` (ridge regressions on the inclination features, a hand-written
ONNX graph) is registered here and then trained, exported, served and recalibrated
by the library's own entry points; no library file names it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from toy_family import RidgeConfig, RidgeTraining, ridge_fit

from serving.families import family_for
from serving.predictor import Predictor
from stiffnet.config import validate_config
from stiffnet.errors import ConfigError, StiffnetError
from stiffnet.io_utils import sha256_file
from stiffnet.recordings import read_recording
from training.config import TrainConfig
from training.families import families, family_for_model, get_family, register_family

EXAMPLE = "examples/recordings/impact_beta45.csv"


@pytest.fixture(scope="module")
def toy(tiny_dir, tmp_path_factory):
    register_family(RidgeTraining)
    from training.train import train

    cfg = validate_config(TrainConfig, {"family": "ridge", "ridge": {"alpha": 3.0},
                                        "tracking": False})  # fmt: skip
    out = tmp_path_factory.mktemp("toy") / "model"
    return train(tiny_dir, cfg, out, progress=None), cfg


def test_ridge_fit_matches_the_normal_equations():
    rng = np.random.default_rng(0)
    X = rng.normal(3.0, [1.0, 10.0, 0.1], size=(200, 3))
    y = X @ [1.0, -0.2, 4.0] + 0.5
    W, b = ridge_fit(X, y[:, None], 1e-9)
    np.testing.assert_allclose(W[:, 0], [1.0, -0.2, 4.0], rtol=1e-6)
    np.testing.assert_allclose(b, [0.5], atol=1e-5)


def test_registry_lists_the_toy_beside_the_shipped_families(toy):
    assert {"cnn", "gbm", "ridge"} <= set(families())
    assert family_for("test.ridge") is RidgeTraining.serving
    assert isinstance(family_for_model("test.ridge"), RidgeTraining)
    with pytest.raises(StiffnetError, match="'svm' is not available: use .*ridge"):
        get_family("svm")


def test_config_sections_are_the_families(toy):
    _, cfg = toy
    assert cfg.model == "ridge" and cfg.section == RidgeConfig(alpha=3.0)
    assert cfg.experiment == "stiffnet-ridge"
    assert cfg.gbm.max_iter == 500  # every registered family's section, with its defaults
    # a lone section names the family; an unknown section or a bad value is one line
    assert validate_config(TrainConfig, {"ridge": {"alpha": 2}}).model == "ridge"
    with pytest.raises(ConfigError, match="unknown field 'svm'"):
        validate_config(TrainConfig, {"svm": {}})
    with pytest.raises(ConfigError, match="disagree"):
        validate_config(TrainConfig, {"model": "ridge", "family": "gbm"})
    with pytest.raises(ConfigError, match="ridge.alpha"):
        validate_config(TrainConfig, {"ridge": {"alpha": -1}})


def test_toy_trains_and_exports_with_the_shared_tail(toy):
    summary, _ = toy
    paths = summary["paths"]
    card = json.loads(open(paths["card"]).read())
    assert paths["onnx"].endswith("ridge.onnx") and card["sha256"] == sha256_file(paths["onnx"])
    assert card["model"] == "ridge" and card["metadata"]["model_kind"] == "test.ridge"
    # the shared tail calibrated an interval and an alarm, and checked parity
    assert np.isfinite(summary["conformal_quantile"]) and summary["conformal_quantile"] > 0
    assert card["metadata"]["alarm_sha256"] == sha256_file(paths["alarm"])
    assert summary["parity"]["max_abs_proba_diff"] < 1e-4
    assert summary["parity"]["max_abs_log_beta_diff"] < 1e-3
    assert 0.0 <= summary["metrics"]["accuracy"] <= 1.0  # named as every family's


def test_predictor_serves_the_toy(toy):
    summary, _ = toy
    pred = Predictor.load(summary["paths"]["onnx"])
    rec = read_recording(EXAMPLE)
    res = pred.predict(rec.accel, rec.fs_hz, natural_frequency_hz=9.48)
    assert res["model"]["kind"] == "ridge"
    assert res["beta"] > 0 and res["beta_interval"][0] < res["beta"] < res["beta_interval"][1]
    probs = np.array(list(res["probabilities"].values()))
    assert probs.min() >= 0 and abs(probs.sum() - 1) < 1e-5


def test_recalibration_refits_through_the_family(toy, tiny_dir):
    from training.recalibrate import recalibrate

    summary, cfg = toy
    before = json.loads(open(summary["paths"]["card"]).read())
    new = cfg.model_copy(update={"alarm_false_alarm": 0.3})
    res = recalibrate(summary["paths"]["onnx"], tiny_dir, new)
    after = json.loads(open(summary["paths"]["card"]).read())
    assert after["sha256"] == sha256_file(summary["paths"]["onnx"])
    assert after["metadata"]["alarm_sha256"] == sha256_file(summary["paths"]["alarm"])
    assert after["metadata"]["alarm_sha256"] != before["metadata"]["alarm_sha256"]
    # the same model, data and split: the same interval (the alarm's target changed)
    q = after["metadata"]["conformal_quantile_recording"]
    assert q == before["metadata"]["conformal_quantile_recording"]
    assert res["thresholds"] and set(res) >= {"conformal_quantile_recording", "thresholds"}
    Predictor.load(summary["paths"]["onnx"])  # still verifies against its card


def test_loop_family_option_and_deprecated_model(tmp_path):
    """`loop --model` still names a family (with a note); a wrong one fails before any work."""
    from typer.testing import CliRunner

    from stiffnet.cli import app

    state = tmp_path / "state"
    args = ["loop", "examples/recordings", "--state", str(state)]
    res = CliRunner().invoke(app, [*args, "--model", "svm"])
    assert res.exit_code == 2 and "`loop --model` is deprecated" in res.output
    assert "model family 'svm' is not available" in res.output
    res = CliRunner().invoke(app, [*args, "--model", "gbm", "--family", "cnn"])
    assert res.exit_code == 2 and "disagree" in res.output
    assert not state.exists()
