"""The training tail every model family shares: calibrate, evaluate, export, track.

:func:`training.train.train` loads the data, asks the family
(:mod:`training.families`) for its inputs, splits by trajectory and lets the
family fit; the family's :class:`~training.families.base.TrainedModel` goes to
:func:`finish_training`, which then, the same way for every family:

1. :func:`calibrate`: the per-window split-conformal log-beta half-width on the
   calibration trajectories' contact windows, and the recording-level interval
   and alarm on whole calibration trajectories
   (:func:`training.uncertainty_calibration.calibrate_recording_level`);
2. :func:`evaluate_test`: the model on the test windows (``accuracy``, ...,
   and ``recording/...`` on the test trajectories) and the geometric method on
   the same windows (``geometric/...``, :mod:`training.geometric_baseline`). The
   names are the same for every family (the family is a parameter and a tag), so
   MLflow compares runs of different families column by column;
3. :func:`export_model`: the alarm reference, the ONNX model with its metadata
   (the interval, the alarm's SHA-256, the training data's natural frequency and
   class edges, and the family's own contract) and model card, and the parity of
   the ONNX model with the fitted one;
4. :func:`track_run` logs the run to MLflow when tracking is on, and
   ``summary.json`` is written.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.dataset.store import CARD
from stiffnet.io_utils import sha256_file, write_json_atomic
from stiffnet.uncertainty import conformal_quantile
from stiffnet.uncertainty.alarm import AlarmReference, save_alarm
from training.config import TrainConfig
from training.families.base import TrainedModel
from training.geometric_baseline import geometric_baseline
from training.metrics import NO_CONTACT_LABEL, confusion, evaluate
from training.split import Split
from training.training_data import alarm_info, data_summary
from training.uncertainty_calibration import calibrate_recording_level

#: The alarm reference sits beside its model: ``cnn.onnx`` -> ``cnn.alarm.npz``.
ALARM_SUFFIX = ".alarm.npz"
#: How the shipped interval is calibrated (model metadata ``interval``).
INTERVAL_METHOD = "normalised split-conformal, one score per trajectory"


@dataclass
class Calibration:
    """What :func:`calibrate` decides: the interval's half-widths and the alarm."""

    window_quantile: float  # per-window log-beta half-width
    recording_quantile: float  # normalised, one score per trajectory
    alarm: AlarmReference
    recording_metrics: dict[str, float]  # the test trajectories'


def calibrate(
    model: TrainedModel, ds: Any, split: Split, config: TrainConfig, card_sha: str,
    say: Callable[[str], None],
) -> Calibration:  # fmt: skip
    """The interval (per window and per recording) and the alarm, on the calibration split."""
    label, beta, outputs = ds.column("label"), ds.column("beta"), model.outputs
    cal = split.cal & (label != NO_CONTACT_LABEL)
    q = conformal_quantile(np.log(beta[cal]) - outputs["log_beta"][cal], config.coverage)
    say(f"conformal half-width (log beta, {config.coverage:.0%}): {q:.3f} from {cal.sum()} windows")
    alarm, q_rec, m_rec = calibrate_recording_level(
        ds.column("trajectory"), label, beta, split, outputs, config.coverage,
        config.alarm_false_alarm, config.seed, alarm_info(ds, card_sha), config.alarm_checks,
        model.classes,
    )  # fmt: skip
    say(
        f"per-trajectory conformal quantile {q_rec:.3f} (normalised); alarm thresholds "
        f"{ {k: round(v, 4) for k, v in alarm.thresholds.items()} }; test trajectories: "
        + ", ".join(f"{k} {v:.3f}" for k, v in m_rec.items())
    )
    return Calibration(q, q_rec, alarm, m_rec)


def evaluate_test(
    model: TrainedModel, ds: Any, split: Split, config: TrainConfig, calib: Calibration,
    say: Callable[[str], None],
) -> tuple[dict[str, float], dict[str, np.ndarray], float]:  # fmt: skip
    """Test metrics of the model and the geometric method on the same windows.

    Returns the metrics (the model's unprefixed, ``recording/...``, ``geometric/...``),
    the confusion matrices by method and the geometric method's seconds.
    """
    names = ds.class_names
    label, beta, noise = ds.column("label"), ds.column("beta"), ds.column("noise")
    te, q = split.test, calib.window_quantile
    proba, log_b = model.outputs["probabilities"][te], model.outputs["log_beta"][te]
    pred = model.classes[proba.argmax(axis=1)] if len(proba) else np.empty(0, np.int64)
    metrics = evaluate(
        label[te], pred, beta[te], np.exp(log_b.astype(np.float64)), noise[te], names,
        config.noise_bins, lo=np.exp(log_b - q), hi=np.exp(log_b + q),
    )  # fmt: skip
    metrics.update({f"recording/{k}": v for k, v in calib.recording_metrics.items()})
    windows = ds.windows()
    g_pred, t_geo = geometric_baseline(
        [np.asarray(windows[i], dtype=np.float64) for i in np.flatnonzero(te)],
        ds.column("fs_hz")[te], label[te], beta[te], noise[te], names, config, metrics,
        model.name, say,
    )  # fmt: skip
    confusions = {
        model.name: confusion(label[te], pred, len(names)),
        "geometric": confusion(label[te], g_pred, len(names)),
    }
    return metrics, confusions, t_geo


def export_model(
    model: TrainedModel, ds: Any, data_dir: Path, out_dir: Path, card_sha: str, split: Split,
    config: TrainConfig, calib: Calibration, metrics: dict[str, float],
) -> tuple[Path, dict[str, Any]]:  # fmt: skip
    """Write the alarm reference, then the ONNX model and its card; returns (path, card)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    onnx_path = out_dir / f"{model.name}.onnx"
    alarm_path = onnx_path.with_suffix(ALARM_SUFFIX)
    save_alarm(alarm_path, calib.alarm)
    data = data_summary(data_dir, card_sha, ds)
    metadata = {
        "training_data_sha256": card_sha,
        "conformal_quantile": calib.window_quantile,
        "conformal_coverage": config.coverage,
        **model.metadata,
        "interval": INTERVAL_METHOD,
        "conformal_quantile_recording": calib.recording_quantile,
        "alarm_reference": alarm_path.name,
        "alarm_sha256": sha256_file(alarm_path),
        # self-describing: the rig the model was trained for, and where its classes end
        "natural_frequency_hz": data["natural_frequency_hz"],
        "class_edges": calib.alarm.info.get("class_edges"),
    }
    card = {
        "kind": "stiffnet-model-card",
        "model": model.name,
        **model.versions,
        "config": config.model_dump(mode="json"),
        "data": data,
        "split_windows": split_sizes(split),
        "metrics": metrics,
        **model.card,
    }
    return onnx_path, model.export(onnx_path, metadata, card)


def split_sizes(split: Split) -> dict[str, int]:
    """Windows in each part of the split."""
    return {k: int(getattr(split, k).sum()) for k in ("train", "val", "cal", "test")}


def finish_training(
    model: TrainedModel,
    *,
    ds: Any,
    data_dir: Path,
    out_dir: Path,
    card_sha: str,
    split: Split,
    config: TrainConfig,
    tracking_uri: str | None,
    say: Callable[[str], None],
    started: float,
) -> dict[str, Any]:
    """Calibrate, evaluate, export and track a fitted model (see the module notes).

    Parameters
    ----------
    model : TrainedModel
        The fitted model and its family's hooks.
    ds : stiffnet.dataset.store.Dataset
        The training dataset.
    data_dir, out_dir : Path
        The dataset folder and the output folder (created).
    card_sha : str
        SHA-256 of the dataset's card.
    split : Split
        The trajectory-wise split the model was fitted on.
    config : TrainConfig
        Training configuration.
    tracking_uri : str or None
        MLflow URI overriding ``config.tracking_uri``.
    say : callable
        Receives one-line progress messages.
    started : float
        ``time.perf_counter()`` at the start of the run (``timing.total_s``; the
        MLflow run starts then too).

    Returns
    -------
    dict
        The run's summary (also written to ``out_dir/summary.json``).
    """
    calib = calibrate(model, ds, split, config, card_sha, say)
    metrics, confusions, t_geo = evaluate_test(model, ds, split, config, calib, say)
    onnx_path, card = export_model(model, ds, data_dir, out_dir, card_sha, split, config,
                                   calib, metrics)  # fmt: skip
    Xt = model.inputs[split.test]
    par = model.parity(onnx_path, Xt if len(Xt) else model.inputs)
    say(f"exported {onnx_path} (sha256 {card['sha256'][:12]}); parity {par}")

    started_at = time.time() - (time.perf_counter() - started)
    tracked = track_run(
        config, tracking_uri, data_dir, ds, card_sha, onnx_path, say,
        params=model.params,
        metrics={**metrics, "conformal_quantile": calib.window_quantile, **model.metrics,
                 **{f"parity/{k}": v for k, v in par.items()}},
        confusions=confusions, history=model.history, started_at=started_at,
    )  # fmt: skip
    summary = {
        "family": model.name,
        "metrics": metrics,
        "conformal_quantile": calib.window_quantile,
        "parity": par,
        "split_windows": split_sizes(split),
        "run_id": tracked.get("run_id"),
        "registered_model": tracked.get("registered_model"),
        "model_version": tracked.get("model_version"),
        **model.summary,
        "paths": {
            "onnx": str(onnx_path),
            "card": str(onnx_path.with_suffix(".card.json")),
            "alarm": str(onnx_path.with_suffix(ALARM_SUFFIX)),
            "summary": str(out_dir / "summary.json"),
        },
        "conformal_quantile_recording": calib.recording_quantile,
        "timing": {
            **{k: round(v, 3) for k, v in model.timing.items()},
            "geometric_s": round(t_geo, 3),
            "total_s": round(time.perf_counter() - started, 3),
        },
    }
    write_json_atomic(out_dir / "summary.json", summary)
    say(f"done in {summary['timing']['total_s']:.1f} s")
    return summary


def run_name(family: str, data_dir: Path, started_at: float) -> str:
    """What ran: ``FAMILY on DATASET at UTC-TIME`` (MLflow's run name)."""
    when = datetime.fromtimestamp(started_at, tz=UTC).strftime("%Y-%m-%d %H:%M:%SZ")
    return f"{family} on {Path(data_dir).resolve().name} at {when}"


def track_run(
    config: TrainConfig,
    tracking_uri: str | None,
    data_dir: Path,
    ds: Any,
    card_sha: str,
    onnx_path: Path,
    say: Callable[[str], None],
    *,
    params: dict[str, Any],
    metrics: dict[str, float],
    confusions: dict[str, np.ndarray],
    history: list[dict[str, float]] | None = None,
    started_at: float | None = None,
) -> dict[str, Any]:
    """Log the run to MLflow (when tracking is on) and register its model.

    Returns ``run_id``, ``registered_model`` and ``model_version`` (empty without tracking).
    """
    if not config.tracking:
        return {}
    from training.tracking import log_run

    uri = tracking_uri or config.tracking_uri
    family = str(config.model)
    started_at = time.time() if started_at is None else started_at
    common = {
        "family": family,
        "model": family,  # the name runs before the family plugins carried
        "seed": config.seed,
        "test_fraction": config.test_fraction,
        "calibration_fraction": config.calibration_fraction,
        "coverage": config.coverage,
        "data_card_sha256": card_sha,
        "n_windows": len(ds),
    }
    registered = config.registered_model
    out = log_run(
        tracking_uri=uri,
        experiment=str(config.experiment),
        run_name=run_name(family, data_dir, started_at),
        start_time=started_at,
        params={**common, **params},
        metrics=metrics,
        data_card_path=data_dir / CARD,
        dataset={
            "name": Path(data_dir).resolve().name,
            "digest": card_sha,
            "source": Path(data_dir).resolve().as_uri(),
            "n_windows": len(ds),
            "n_trajectories": ds.card.get("n_trajectories"),
        },  # fmt: skip
        artifacts=[
            p
            for p in (
                onnx_path,
                onnx_path.with_suffix(".card.json"),
                onnx_path.with_suffix(ALARM_SUFFIX),
            )
            if p.is_file()
        ],
        confusions=confusions,
        class_names=ds.class_names,
        tags={
            "stiffnet.family": family,
            "stiffnet.model": family,
            "stiffnet.data_sha256": card_sha,
        },  # fmt: skip
        history=history,
        onnx_model=onnx_path,
        registered_model=registered or None,
    )
    version = f", registered {registered} v{out['model_version']}" if registered else ""
    say(f"MLflow run {out['run_id']} in {uri} (experiment {config.experiment}{version})")
    return {**out, "registered_model": registered or None}
