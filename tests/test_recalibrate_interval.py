"""The interval recalibrated on an independent calibration set (``recalibrate
--calibration-set``): only the recording-level conformal quantile changes, and it is the
split-conformal quantile of that set's own scores."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from stiffnet.io_utils import sha256_file
from tests.conftest import TINY_DATASET


@pytest.fixture(scope="module")
def model_and_other_set(tiny_dir, tmp_path_factory):
    from stiffnet.config import validate_config
    from stiffnet.config.sim import SimulationConfig
    from stiffnet.dataset.generate import generate_dataset
    from training.config import TrainConfig
    from training.train import train

    work = tmp_path_factory.mktemp("recal")
    cfg = TrainConfig(experiment="test-recal", gbm={"max_iter": 40, "min_samples_leaf": 5})
    summary = train(tiny_dir, cfg, work / "out", tracking_uri=f"sqlite:///{work / 'm.db'}",
                    progress=None)  # fmt: skip
    other = work / "cal"
    generate_dataset(validate_config(SimulationConfig, {**TINY_DATASET, "seed": 991}), other)
    return Path(summary["paths"]["onnx"]), other


def test_calibration_set_refits_the_quantile_only(model_and_other_set, tiny_dir, tmp_path):
    from typer.testing import CliRunner

    from stiffnet.cli import app
    from stiffnet.dataset.store import load_dataset
    from stiffnet.uncertainty.alarm import load_alarm
    from training.recalibrate import column_classes, model_outputs
    from training.uncertainty_calibration import trajectory_table

    src, other = model_and_other_set
    for f in src.parent.glob("gbm.*"):
        shutil.copy(f, tmp_path / f.name)
    model = tmp_path / "gbm.onnx"
    before = json.loads((tmp_path / "gbm.card.json").read_text())
    alarm_sha = sha256_file(tmp_path / "gbm.alarm.npz")
    args = ["recalibrate", str(model), "--data", str(other), "--calibration-set"]
    res = CliRunner().invoke(app, [*args, "--json", str(tmp_path / "r.json")])
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "r.json").read_text())
    after = json.loads((tmp_path / "gbm.card.json").read_text())
    q = after["metadata"]["conformal_quantile_recording"]
    assert q == pytest.approx(out["conformal_quantile_recording"])
    assert out["previous"] == pytest.approx(before["metadata"]["conformal_quantile_recording"])
    assert after["metadata"]["calibration_data_sha256"] == sha256_file(other / "card.json")
    assert after["sha256"] == sha256_file(model)
    assert sha256_file(tmp_path / "gbm.alarm.npz") == alarm_sha  # the alarm is kept
    # the quantile is the set's own: (1 - alpha)(1 + 1/n) of its contact trajectories' scores
    ds = load_dataset(other)
    table = trajectory_table(ds.column("trajectory"), ds.column("label"), ds.column("beta"),
                             model_outputs(model, ds, after["metadata"]),
                             load_alarm(tmp_path / "gbm.alarm.npz"),
                             classes=column_classes(after["metadata"]))  # fmt: skip
    ok = (table.label != 0) & np.isfinite(table.log_beta)
    covered = np.abs(table.log_beta[ok] - np.log(table.beta[ok])) <= q * table.scale[ok] + 1e-12
    assert covered.mean() >= 0.9 and out["coverage"] == pytest.approx(covered.mean())
    # the training data is not a calibration set
    bad = CliRunner().invoke(app, ["recalibrate", str(model), "--data", str(tiny_dir),
                                   "--calibration-set"])  # fmt: skip
    assert bad.exit_code == 2 and "independent" in bad.output
