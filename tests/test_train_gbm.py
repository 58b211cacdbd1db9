"""GBM training end to end on a tiny dataset: split, ONNX export and parity, MLflow run."""

import json
from pathlib import Path

import numpy as np
import onnx
import pytest

from stiffnet.config import load_config, validate_config
from stiffnet.dataset.store import load_dataset
from stiffnet.errors import ConfigError
from stiffnet.features import FEATURE_NAMES, feature_matrix
from stiffnet.io_utils import sha256_file
from stiffnet.uncertainty import conformal_quantile
from training.config import TrainConfig
from training.families.gbm.export import export_onnx, onnx_predict
from training.families.gbm.model import fit_gbm
from training.metrics import noise_bins
from training.split import trajectory_split


@pytest.fixture(scope="session")
def trained(tiny_dir, tmp_path_factory):
    from training.train import train

    work = tmp_path_factory.mktemp("run")
    uri = f"sqlite:///{work / 'mlflow.db'}"
    cfg = TrainConfig(experiment="test-gbm", gbm={"max_iter": 60, "min_samples_leaf": 5})
    summary = train(tiny_dir, cfg, work / "out", tracking_uri=uri, progress=None)
    return summary, uri, work


def test_default_yaml_restates_defaults():
    assert load_config(TrainConfig, "configs/train/gbm.yaml") == TrainConfig()
    with pytest.raises(ConfigError, match="test_fraction"):
        validate_config(TrainConfig, {"test_fraction": 1.5})
    with pytest.raises(ConfigError, match="learning_rate"):
        validate_config(TrainConfig, {"gbm": {"learning_rate": 0}})
    with pytest.raises(ConfigError, match="undo_chain must be one of off, chain"):
        validate_config(TrainConfig, {"undo_chain": "everything"})
    assert validate_config(TrainConfig, {"undo_chain": "outside_priors"}).undo_chain == (
        "outside_priors"
    )


def test_trajectory_split_has_no_leakage():
    traj = np.repeat(np.arange(50), 3)
    sp = trajectory_split(traj, 0.2, 0.2, 0.15, seed=1)
    parts = [set(traj[m]) for m in (sp.train, sp.val, sp.cal, sp.test)]
    for i in range(4):
        assert parts[i]
        for j in range(i + 1, 4):
            assert not parts[i] & parts[j]
    assert sum(len(p) for p in parts) == 50
    assert (sp.train.astype(int) + sp.val + sp.cal + sp.test == 1).all()
    again = trajectory_split(traj, 0.2, 0.2, 0.15, seed=1)
    np.testing.assert_array_equal(again.test, sp.test)


def test_conformal_quantile_and_noise_bins():
    r = np.arange(1, 11, dtype=float)
    assert conformal_quantile(r, 0.9) == 10.0  # ceil(11 * 0.9) = 10th smallest
    assert conformal_quantile(r, 0.5) == 6.0
    assert conformal_quantile(r[:3], 0.9) == float("inf")
    idx = noise_bins(np.array([0.0, 0.01, 0.02, 0.05, 0.08, 0.1]), [0.0, 0.02, 0.05, 0.09])
    np.testing.assert_array_equal(idx, [0, 1, 1, 2, 3, 4])


def test_training_writes_onnx_with_card_and_metadata(trained, tiny_dir):
    summary, _, _ = trained
    path = summary["paths"]["onnx"]
    card = json.loads(open(summary["paths"]["card"]).read())
    assert card["sha256"] == sha256_file(path)
    assert card["data"]["card_sha256"] == sha256_file(tiny_dir / "card.json")
    m = onnx.load(path)
    meta = {p.key: p.value for p in m.metadata_props}
    assert json.loads(meta["feature_names"]) == FEATURE_NAMES
    names = load_dataset(tiny_dir).class_names
    onnx_names = json.loads(meta["class_names"])
    assert onnx_names == [names[i] for i in json.loads(meta["class_indices"])]
    assert meta["training_data_sha256"] == sha256_file(tiny_dir / "card.json")
    assert meta["beta_transform"] == "log" and meta["model_kind"] == "stiffnet.gbm"
    assert float(meta["conformal_quantile"]) == pytest.approx(summary["conformal_quantile"])
    assert m.graph.input[0].type.tensor_type.elem_type == onnx.TensorProto.FLOAT
    assert m.graph.input[0].type.tensor_type.shape.dim[0].dim_param == "N"  # dynamic batch
    assert [o.name for o in m.graph.output] == ["label", "probabilities", "log_beta"]
    # self-describing: the feature contract (the tiny set's windows are 8 periods long),
    # the training rig's f_n and the class edges
    contract = json.loads(meta["feature_contract"])
    assert contract["feature_version"] == json.loads(meta["feature_version"])
    assert json.loads(meta["window_periods"]) == contract["cut"]["window_periods"] == 8
    assert json.loads(meta["natural_frequency_hz"]) == card["data"]["natural_frequency_hz"]
    assert len(json.loads(meta["class_edges"])) == len(names)  # no_contact has no edge
    for key in ("accuracy", "geometric/accuracy", "macro_f1", "beta_mape"):
        assert key in summary["metrics"]
    bins = {k.split("/")[0] for k in summary["metrics"] if k.startswith("noise_")}
    assert bins and bins <= {"noise_0", "noise_0.05", "noise_gt0.09"}  # levels 0, 3 %, 12 %
    assert {f"geometric/{b}/accuracy" for b in bins} <= set(summary["metrics"])
    assert summary["parity"]["max_abs_proba_diff"] < 1e-4
    assert summary["parity"]["max_rel_beta_diff"] < 1e-4


def test_onnx_parity_with_sklearn(tiny_dir, tmp_path):
    ds = load_dataset(tiny_dir)
    X = feature_matrix(ds.windows(), ds.column("fs_hz"), ds.column("natural_frequency_hz"))
    label, beta = ds.column("label"), ds.column("beta")
    sp = trajectory_split(ds.column("trajectory"), 0.2, 0.2, 0.15, seed=0)
    cfg = TrainConfig(gbm={"max_iter": 40, "min_samples_leaf": 5}).gbm
    clf, reg = fit_gbm(X, label, beta, sp, cfg, seed=0)
    path = tmp_path / "m.onnx"
    export_onnx(
        clf,
        reg,
        FEATURE_NAMES,
        ds.class_names,
        path,
        metadata={"training_data_sha256": "x", "conformal_quantile": 0.1},
        card={},
    )
    # random rows too, well away from the training data
    rng = np.random.default_rng(0)
    Xr = np.vstack([X, X[rng.integers(0, len(X), 50)] * rng.uniform(0.5, 1.5, (50, X.shape[1]))])
    X32 = Xr.astype(np.float32)
    out = onnx_predict(path, X32)
    p = clf.predict_proba(X32.astype(np.float64))
    b = np.exp(reg.predict(X32.astype(np.float64)))
    np.testing.assert_allclose(out["probabilities"], p, atol=1e-4)
    np.testing.assert_allclose(out["beta"], b, rtol=1e-4)
    np.testing.assert_array_equal(out["label"], clf.predict(X32.astype(np.float64)))
    assert out["probabilities"].shape == (len(Xr), len(clf.classes_))


def test_mlflow_run_has_both_methods(trained, tiny_dir):
    import mlflow

    summary, uri, work = trained
    client = mlflow.MlflowClient(tracking_uri=uri)
    run = client.get_run(summary["run_id"])
    assert "accuracy" in run.data.metrics and "geometric/accuracy" in run.data.metrics
    assert run.data.params["family"] == "gbm" and run.data.tags["stiffnet.family"] == "gbm"
    # a name that says what ran, and a run that covers the training, not only its logging
    assert run.info.run_name.startswith("gbm on ds at ")
    assert (run.info.end_time - run.info.start_time) / 1e3 >= 0.9 * summary["timing"]["total_s"]
    # the dataset is the run's input, identified by its card's SHA-256
    (inp,) = run.inputs.dataset_inputs
    card_sha = sha256_file(tiny_dir / "card.json")
    assert inp.dataset.name == "ds" and card_sha.startswith(inp.dataset.digest)
    assert {t.key: t.value for t in inp.tags}["sha256"] == card_sha
    # the model is registered (as the loop's are), its version in the summary
    assert summary["registered_model"] == "stiffnet-gbm" and summary["model_version"] >= 1
    version = client.get_model_version("stiffnet-gbm", str(summary["model_version"]))
    assert version.run_id == summary["run_id"]
    arts = {
        a.path
        for d in ("data", "model", "figures")
        for a in client.list_artifacts(run.info.run_id, d)
    }
    assert {"data/card.json", "model/gbm.onnx", "model/gbm.card.json"} <= arts
    assert {"figures/gbm.png", "figures/geometric.png"} <= arts
    location = client.get_experiment(run.info.experiment_id).artifact_location
    assert location == (work / "mlruns").as_uri()  # beside the database, not in the cwd


def test_train_cli_writes_model_and_json(tiny_dir, tmp_path):
    from typer.testing import CliRunner

    from stiffnet.cli import app

    cfg = tmp_path / "gbm.yaml"
    cfg.write_text("gbm: {max_iter: 30, min_samples_leaf: 5}\ntracking: false\n")
    runner = CliRunner()
    res = runner.invoke(
        app, ["train", "--data", str(tiny_dir), "--config", str(cfg), "--out",
              str(tmp_path / "m"), "--json", str(tmp_path / "r.json")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    result = json.loads((tmp_path / "r.json").read_text())
    assert 0.0 <= result["metrics"]["accuracy"] <= 1.0 and result["family"] == "gbm"
    assert (tmp_path / "m" / "gbm.onnx").is_file()
    bad = runner.invoke(app, ["train", "--data", str(tmp_path / "nope"), "--out",
                              str(tmp_path / "m2")])  # fmt: skip
    assert bad.exit_code == 2 and "not a finished stiffnet dataset" in bad.output
    bad = runner.invoke(app, ["train", "--data", str(tiny_dir), "--model", "svm"])
    assert bad.exit_code == 2 and "not available" in bad.output
    bad = runner.invoke(
        app, ["train", "--data", str(tiny_dir), "--model", "cnn", "--config", str(cfg)]
    )
    assert bad.exit_code == 2 and "trains 'gbm', not 'cnn'" in bad.output


def test_train_cli_family_option_and_deprecated_model(tiny_dir, tmp_path):
    from typer.testing import CliRunner

    from stiffnet.cli import app

    cfg = tmp_path / "gbm.yaml"
    cfg.write_text("gbm: {max_iter: 20, min_samples_leaf: 5}\ntracking: false\n")
    runner = CliRunner()
    args = ["train", "--data", str(tiny_dir), "--config", str(cfg)]
    res = runner.invoke(app, [*args, "--family", "gbm", "--out", str(tmp_path / "a")])
    assert res.exit_code == 0, res.output
    assert "deprecated" not in res.output
    res = runner.invoke(app, [*args, "--model", "gbm", "--out", str(tmp_path / "b")])
    assert res.exit_code == 0, res.output
    assert "`train --model` is deprecated" in res.output and "--family" in res.output
    # the two spellings train the same model
    assert (tmp_path / "a/gbm.onnx").read_bytes() == (tmp_path / "b/gbm.onnx").read_bytes()
    bad = runner.invoke(app, [*args, "--model", "gbm", "--family", "cnn"])
    assert bad.exit_code == 2 and "disagree" in bad.output
    bad = runner.invoke(app, ["train", "--data", str(tiny_dir), "--family", "svm"])
    # the families on offer come from the registry (a test may have added a toy one)
    assert bad.exit_code == 2 and "'svm' is not available: use " in bad.output
    assert {"cnn", "gbm"} <= set(bad.output.split("use ", 1)[1].strip().split(" or "))


def test_families_and_recalibrate_commands(trained, tiny_dir, tmp_path):
    import shutil

    from typer.testing import CliRunner

    from stiffnet.cli import app

    runner = CliRunner()
    res = runner.invoke(app, ["families", "--json", str(tmp_path / "f.json")])
    assert res.exit_code == 0, res.output
    listed = {f["family"]: f for f in json.loads((tmp_path / "f.json").read_text())}
    assert listed["gbm"]["default_of"] == ["train"] and listed["cnn"]["default_of"] == ["loop"]
    assert listed["gbm"]["model_kind"] == "stiffnet.gbm"
    # recalibrate a copy of the trained model (its own config, a looser alarm)
    summary, _, _ = trained
    src = Path(summary["paths"]["onnx"])
    for f in src.parent.glob("gbm.*"):
        shutil.copy(f, tmp_path / f.name)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("gbm: {max_iter: 60, min_samples_leaf: 5}\nalarm_false_alarm: 0.3\n")
    before = json.loads((tmp_path / "gbm.card.json").read_text())
    res = runner.invoke(app, ["recalibrate", str(tmp_path / "gbm.onnx"), "--data",
                              str(tiny_dir), "--config", str(cfg), "--json",
                              str(tmp_path / "r.json")])  # fmt: skip
    assert res.exit_code == 0, res.output
    after = json.loads((tmp_path / "gbm.card.json").read_text())
    assert after["sha256"] == sha256_file(tmp_path / "gbm.onnx") != before["sha256"]
    assert after["metadata"]["alarm_sha256"] == sha256_file(tmp_path / "gbm.alarm.npz")
    assert "thresholds" in json.loads((tmp_path / "r.json").read_text())
    assert {k for k in after["metrics"] if k.startswith("recording/")}
    bad = runner.invoke(app, ["recalibrate", str(tmp_path / "gbm.onnx"), "--data",
                              str(tmp_path / "nope")])  # fmt: skip
    assert bad.exit_code == 2
