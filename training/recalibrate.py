"""Recalibrate a trained model's interval and alarm without retraining it.

Runs the exported ONNX model over the dataset it was trained on, splits the
trajectories exactly as training did (same seed and fractions), refits the
recording-level conformal quantile and the alarm
(:func:`training.calibration.calibrate_recording_level`), writes the new
``NAME.alarm.npz`` and updates the model's metadata and card (SHA-256s
included). Use it when the alarm's checks or its false-alarm target change.

Run: ``OMP_NUM_THREADS=1 python -m training.recalibrate MODEL.onnx DATA_DIR
[--config configs/train/cnn.yaml]``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import onnx
from onnx import helper

from stiffnet.config import load_config
from stiffnet.config.train import TrainConfig
from stiffnet.dataset.store import CARD, load_dataset
from stiffnet.errors import StiffnetError
from stiffnet.io_utils import sha256_file, write_bytes_atomic, write_json_atomic
from stiffnet.shipped import default_config
from stiffnet.uncertainty.alarm import save_alarm
from training.calibration import calibrate_recording_level
from training.export_onnx import onnx_session
from training.finish import ALARM_SUFFIX, INTERVAL_METHOD
from training.split import trajectory_split
from training.training_data import alarm_info


def model_outputs(path: Path, ds: Any, meta: dict[str, Any]) -> dict[str, np.ndarray]:
    """Every output of the ONNX model on every window of `ds`, by output name."""
    sess = onnx_session(path)
    if meta.get("model_kind") == "stiffnet.cnn":
        from stiffnet.features.windows import window_tensor

        X = window_tensor(ds.windows(), ds.column("fs_hz"), ds.column("natural_frequency_hz"),
                          int(meta["canonical_rate"]), int(meta["window_periods"]),
                          meta["delays"])  # fmt: skip
    else:
        from training.transformers import InclinationFeatures, window_records

        X = (
            InclinationFeatures(bool(meta.get("requires_natural_frequency", True)))
            .fit_transform(window_records(ds))
            .astype(np.float32)
        )
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
    fit = config.cnn if config.model == "cnn" else config.gbm
    val = fit.validation_fraction
    sp = trajectory_split(ds.column("trajectory"), config.test_fraction,
                          config.calibration_fraction, val, config.seed)  # fmt: skip
    outputs = model_outputs(path, ds, meta)
    alarm, q_rec, m_rec = calibrate_recording_level(
        ds.column("trajectory"), ds.column("label"), ds.column("beta"), sp, outputs,
        config.coverage, config.alarm_false_alarm, config.seed, alarm_info(ds, card_sha),
        config.alarm_checks,
    )  # fmt: skip
    alarm_path = path.with_suffix(ALARM_SUFFIX)
    save_alarm(alarm_path, alarm)
    update = {
        "conformal_quantile_recording": q_rec,
        "interval": INTERVAL_METHOD,
        "alarm_reference": alarm_path.name,
        "alarm_sha256": sha256_file(alarm_path),
    }
    model = onnx.load(str(path))
    props = {p.key: p.value for p in model.metadata_props}
    props.update({k: v if isinstance(v, str) else json.dumps(v) for k, v in update.items()})
    del model.metadata_props[:]
    helper.set_model_props(model, props)
    write_bytes_atomic(path, model.SerializeToString())
    kind = "cnn" if meta.get("model_kind") == "stiffnet.cnn" else "gbm"
    metrics = {k: v for k, v in (card.get("metrics") or {}).items()
               if not k.startswith(f"{kind}/recording/")}  # fmt: skip
    metrics.update({f"{kind}/recording/{k}": v for k, v in m_rec.items()})
    card.update(sha256=sha256_file(path), metadata={**meta, **update}, metrics=metrics)
    write_json_atomic(card_path, card)
    return {"conformal_quantile_recording": q_rec, "thresholds": alarm.thresholds, **m_rec}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("data_dir")
    ap.add_argument("--config", default=None, help="the training config (YAML)")
    args = ap.parse_args(argv)
    try:
        # the shipped config next to the package, never the current folder's
        default = default_config("train/cnn.yaml") if "cnn" in Path(args.model).stem else None
        cfg_path = args.config or default
        cfg = load_config(TrainConfig, cfg_path) if cfg_path else TrainConfig()
        print(json.dumps(recalibrate(args.model, args.data_dir, cfg), indent=1))
    except StiffnetError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
