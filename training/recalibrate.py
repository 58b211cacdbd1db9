"""Recalibrate a trained model's interval and alarm without retraining it.

Runs the exported ONNX model over the dataset it was trained on, splits the
trajectories exactly as training did (same seed and fractions), refits the
recording-level conformal quantile and the alarm
(:func:`training.uncertainty_calibration.calibrate_recording_level`), writes the new
``NAME.alarm.npz`` and updates the model's metadata and card (SHA-256s
included). Use it when the alarm's checks or its false-alarm target change.

Library use: ``recalibrate(model, data, recalibration_config(model))``; the
command line is ``stiffnet recalibrate MODEL.onnx --data DATA_DIR [--config FILE]``.
With ``--calibration-set`` the data is an independent set simulated from the current
priors instead (:func:`recalibrate_interval`): only the interval's quantile is refitted.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.config import load_config, validate_config
from stiffnet.dataset.store import CARD, load_dataset
from stiffnet.errors import StiffnetError
from stiffnet.inputs import read_json
from stiffnet.io_utils import sha256_file
from stiffnet.shipped import default_config
from stiffnet.uncertainty.alarm import save_alarm
from training.config import TrainConfig
from training.families import family_for_model
from training.finish import ALARM_SUFFIX, INTERVAL_METHOD
from training.onnx_export import onnx_session, rewrite_metadata
from training.split import trajectory_split
from training.training_data import alarm_info
from training.uncertainty_calibration import calibrate_recording_level


def model_outputs(path: Path, ds: Any, meta: dict[str, Any]) -> dict[str, np.ndarray]:
    """Every output of the ONNX model on every window of `ds`, by output name.

    The model's family (found by its ``model_kind`` metadata) rebuilds the input
    the model reads from the metadata (:meth:`TrainingFamily.inputs_from_metadata`).
    """
    sess = onnx_session(path)
    X = family_for_model(meta.get("model_kind")).inputs_from_metadata(ds, meta)
    names = [o.name for o in sess.get_outputs() if o.name != "label"]
    parts: dict[str, list[np.ndarray]] = {n: [] for n in names}
    for lo in range(0, len(X), 512):
        for n, v in zip(names, sess.run(names, {sess.get_inputs()[0].name: X[lo : lo + 512]}),
                        strict=True):  # fmt: skip
            parts[n].append(np.asarray(v))
    out = {n: np.concatenate(v).astype(np.float64) for n, v in parts.items()}
    for n in ("log_beta", "log_beta_scale"):
        if n in out:
            out[n] = out[n].reshape(-1)
    return out


def column_classes(meta: dict[str, Any]) -> np.ndarray | None:
    """The class index of each probability column of a model, from its card's metadata
    (``class_indices``; None for a model that does not record them: column k is class k)."""
    idx = meta.get("class_indices")
    if isinstance(idx, str):  # ONNX metadata values are JSON-encoded
        idx = json.loads(idx)
    return None if idx is None else np.asarray(idx, dtype=np.int64)


def recalibrate(model_path: str | Path, data_dir: str | Path, config: TrainConfig) -> dict:
    """Refit the interval and alarm of `model_path` on `data_dir`; returns the new metrics."""
    path, data_dir = Path(model_path), Path(data_dir)
    card_path = path.with_suffix(".card.json")
    card = json.loads(card_path.read_text())
    meta = dict(card.get("metadata") or {})
    ds = load_dataset(data_dir)
    card_sha = sha256_file(data_dir / CARD)
    if meta.get("training_data_sha256") not in (None, card_sha):
        raise StiffnetError(f"{data_dir} is not the data {path.name} was trained on")
    family = family_for_model(meta.get("model_kind"))
    if family.name != config.model:
        raise StiffnetError(
            f"{path.name} is a {family.name} model; the config trains {config.model}"
        )
    val = config.section.validation_fraction
    sp = trajectory_split(ds.column("trajectory"), config.test_fraction,
                          config.calibration_fraction, val, config.seed)  # fmt: skip
    outputs = model_outputs(path, ds, meta)
    alarm, q_rec, m_rec = calibrate_recording_level(
        ds.column("trajectory"), ds.column("label"), ds.column("beta"), sp, outputs,
        config.coverage, config.alarm_false_alarm, config.seed, alarm_info(ds, card_sha),
        config.alarm_checks, column_classes(meta),
    )  # fmt: skip
    alarm_path = path.with_suffix(ALARM_SUFFIX)
    save_alarm(alarm_path, alarm)
    update = {
        "conformal_quantile_recording": q_rec,
        "interval": INTERVAL_METHOD,
        "alarm_reference": alarm_path.name,
        "alarm_sha256": sha256_file(alarm_path),
    }
    # the recording-level metrics are replaced (older cards named them FAMILY/recording/...)
    metrics = {k: v for k, v in (card.get("metrics") or {}).items()
               if not k.startswith(("recording/", f"{family.name}/recording/"))}  # fmt: skip
    metrics.update({f"recording/{k}": v for k, v in m_rec.items()})
    rewrite_metadata(path, update, {"metrics": metrics})
    return {"conformal_quantile_recording": q_rec, "thresholds": alarm.thresholds, **m_rec}


def recalibrate_interval(
    model_path: str | Path, data_dir: str | Path, coverage: float | None = None
) -> dict[str, Any]:
    """Refit only the recording-level conformal quantile on an independent calibration set.

    Every trajectory of `data_dir` (simulated from the current priors, none of them seen in
    training) calibrates the interval; the alarm is kept (refitting it needs the training
    windows' embeddings). The quantile is the split-conformal one of
    :func:`training.uncertainty_calibration.recording_quantile` over the set's contact
    trajectories, so the interval covers at the nominal rate on the world the set was drawn from.

    Returns
    -------
    dict
        ``conformal_quantile_recording`` (new) and ``previous``, the set's
        ``n_trajectories``, and its accuracy, beta MAPE, coverage with the previous and the
        new quantile (in-sample for the new one, by construction near `coverage`).
    """
    from stiffnet.uncertainty.alarm import load_alarm
    from training.uncertainty_calibration import (
        recording_quantile,
        trajectory_metrics,
        trajectory_table,
    )

    path, data_dir = Path(model_path), Path(data_dir)
    card = json.loads(path.with_suffix(".card.json").read_text())
    meta = dict(card.get("metadata") or {})
    ds = load_dataset(data_dir)
    card_sha = sha256_file(data_dir / CARD)
    if meta.get("training_data_sha256") == card_sha:
        raise StiffnetError(
            f"{data_dir} is the data {path.name} was trained on: a calibration set must be "
            "independent (recalibrate without --calibration-set)"
        )
    level = float(coverage or meta.get("conformal_coverage") or 0.9)
    alarm_path = path.with_suffix(ALARM_SUFFIX)
    alarm = load_alarm(alarm_path) if alarm_path.is_file() else None
    outputs = model_outputs(path, ds, meta)
    table = trajectory_table(ds.column("trajectory"), ds.column("label"), ds.column("beta"),
                             outputs, alarm, classes=column_classes(meta))  # fmt: skip
    previous = float(meta.get("conformal_quantile_recording") or np.nan)
    q = recording_quantile(table, level)
    before, after = trajectory_metrics(table, previous), trajectory_metrics(table, q, alarm)
    rewrite_metadata(path, {"conformal_quantile_recording": q,
                            "calibration_data_sha256": card_sha})  # fmt: skip
    return {
        "conformal_quantile_recording": q,
        "previous": previous,
        "n_trajectories": int(len(table.label)),
        "accuracy": after["accuracy"],
        "beta_mape": after.get("beta_mape"),
        "coverage_previous": before.get("coverage"),
        "coverage": after.get("coverage"),
    }


def recalibration_config(model_path: str | Path, config: str | Path | None = None) -> TrainConfig:
    """The training config a model is recalibrated with: `config`, else the shipped
    ``configs/train/FAMILY.yaml`` of the model's family (never the current folder's)."""
    from serving.model import card_path

    card = read_json(card_path(Path(model_path)), "model card")
    meta = (card.get("metadata") or {}) if isinstance(card, dict) else {}
    family = family_for_model(meta.get("model_kind"))
    path = Path(config) if config is not None else default_config(f"train/{family.name}.yaml")
    if path.is_file():
        return load_config(TrainConfig, path)
    return validate_config(TrainConfig, {"model": family.name})
