"""The training tail both model families share: calibrate, evaluate, export, track.

:func:`training.train.train` loads the data, asks the family
(:mod:`training.families`) for its inputs, splits by trajectory and lets the
family fit; the family's :class:`~training.families.base.TrainedModel` goes to
:func:`finish_training`, which then, the same way for every family:

1. calibrates the per-window split-conformal log-beta half-width on the
   calibration trajectories' contact windows, and the recording-level interval
   and alarm on whole calibration trajectories
   (:func:`training.calibration.calibrate_recording_level`);
2. evaluates the model on the test windows (``NAME/...`` metrics, and
   ``NAME/recording/...`` on the test trajectories) and the geometric method
   on the same windows (``geometric/...``, :mod:`training.geometric_baseline`);
3. writes the alarm reference, exports the ONNX model with its metadata and
   model card, and checks the ONNX model against the fitted one (parity);
4. logs the run to MLflow (:func:`training.tracking.log_run`) when tracking is
   on, and writes ``summary.json``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.dataset.store import CARD
from stiffnet.io_utils import sha256_file, write_json_atomic
from stiffnet.uncertainty import conformal_quantile
from stiffnet.uncertainty.alarm import save_alarm
from training.calibration import calibrate_recording_level
from training.config import TrainConfig
from training.families.base import TrainedModel
from training.geometric_baseline import geometric_baseline
from training.metrics import NO_CONTACT_LABEL, confusion, evaluate
from training.split import Split
from training.training_data import alarm_info, data_summary

#: The alarm reference sits beside its model: ``cnn.onnx`` -> ``cnn.alarm.npz``.
ALARM_SUFFIX = ".alarm.npz"
#: How the shipped interval is calibrated (model metadata ``interval``).
INTERVAL_METHOD = "normalised split-conformal, one score per trajectory"


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
        ``time.perf_counter()`` at the start of the run (for ``timing.total_s``).

    Returns
    -------
    dict
        The run's summary (also written to ``out_dir/summary.json``).
    """
    name, names, outputs = model.name, ds.class_names, model.outputs
    label, beta, noise = ds.column("label"), ds.column("beta"), ds.column("noise")

    cal = split.cal & (label != NO_CONTACT_LABEL)
    q = conformal_quantile(np.log(beta[cal]) - outputs["log_beta"][cal], config.coverage)
    say(f"conformal half-width (log beta, {config.coverage:.0%}): {q:.3f} from {cal.sum()} windows")
    alarm, q_rec, m_rec = calibrate_recording_level(
        ds.column("trajectory"), label, beta, split, outputs, config.coverage,
        config.alarm_false_alarm, config.seed, alarm_info(ds, card_sha), config.alarm_checks,
    )  # fmt: skip
    say(
        f"per-trajectory conformal quantile {q_rec:.3f} (normalised); alarm thresholds "
        f"{ {k: round(v, 4) for k, v in alarm.thresholds.items()} }; test trajectories: "
        + ", ".join(f"{k} {v:.3f}" for k, v in m_rec.items())
    )

    te = split.test
    proba, log_b = outputs["probabilities"][te], outputs["log_beta"][te]
    pred = model.classes[proba.argmax(axis=1)] if len(proba) else np.empty(0, np.int64)
    metrics: dict[str, float] = {}
    m_model = evaluate(
        label[te],
        pred,
        beta[te],
        np.exp(log_b.astype(np.float64)),
        noise[te],
        names,
        config.noise_bins,
        lo=np.exp(log_b - q),
        hi=np.exp(log_b + q),
    )
    metrics.update({f"{name}/{k}": v for k, v in m_model.items()})
    metrics.update({f"{name}/recording/{k}": v for k, v in m_rec.items()})
    windows = ds.windows()
    g_pred, t_geo = geometric_baseline(
        [np.asarray(windows[i], dtype=np.float64) for i in np.flatnonzero(te)],
        ds.column("fs_hz")[te], label[te], beta[te], noise[te], names, config, metrics, name, say,
    )  # fmt: skip

    out_dir.mkdir(parents=True, exist_ok=True)
    onnx_path = out_dir / f"{name}.onnx"
    alarm_path = onnx_path.with_suffix(ALARM_SUFFIX)
    save_alarm(alarm_path, alarm)
    splits = {k: int(getattr(split, k).sum()) for k in ("train", "val", "cal", "test")}
    card = model.export(
        onnx_path,
        {
            "training_data_sha256": card_sha,
            "conformal_quantile": q,
            "conformal_coverage": config.coverage,
            **model.metadata,
            "interval": INTERVAL_METHOD,
            "conformal_quantile_recording": q_rec,
            "alarm_reference": alarm_path.name,
            "alarm_sha256": sha256_file(alarm_path),
        },
        {
            "kind": "stiffnet-model-card",
            "model": name,
            **model.versions,
            "config": config.model_dump(mode="json"),
            "data": data_summary(data_dir, card_sha, ds),
            "split_windows": splits,
            "metrics": metrics,
            **model.card,
        },
    )
    Xt = model.inputs[te]
    par = model.parity(onnx_path, Xt if len(Xt) else model.inputs)
    say(f"exported {onnx_path} (sha256 {card['sha256'][:12]}); parity {par}")

    run_id = track_run(
        config, tracking_uri, data_dir, len(ds), card_sha, onnx_path, names, say,
        params=model.params,
        metrics={**metrics, "conformal_quantile": q, **model.metrics,
                 **{f"parity/{k}": v for k, v in par.items()}},
        confusions={
            name: confusion(label[te], pred, len(names)),
            "geometric": confusion(label[te], g_pred, len(names)),
        },
        history=model.history,
    )  # fmt: skip

    summary = {
        "metrics": metrics,
        "conformal_quantile": q,
        "parity": par,
        "split_windows": splits,
        "run_id": run_id,
        **model.summary,
        "paths": {
            "onnx": str(onnx_path),
            "card": str(onnx_path.with_suffix(".card.json")),
            "alarm": str(alarm_path),
            "summary": str(out_dir / "summary.json"),
        },
        "conformal_quantile_recording": q_rec,
        "timing": {
            **{k: round(v, 3) for k, v in model.timing.items()},
            "geometric_s": round(t_geo, 3),
            "total_s": round(time.perf_counter() - started, 3),
        },
    }
    write_json_atomic(out_dir / "summary.json", summary)
    say(f"done in {summary['timing']['total_s']:.1f} s")
    return summary


def track_run(
    config: TrainConfig,
    tracking_uri: str | None,
    data_dir: Path,
    n_windows: int,
    card_sha: str,
    onnx_path: Path,
    names: list[str],
    say: Callable[[str], None],
    *,
    params: dict[str, Any],
    metrics: dict[str, float],
    confusions: dict[str, np.ndarray],
    history: list[dict[str, float]] | None = None,
) -> str | None:
    """Log the run to MLflow (when tracking is on); returns the run id."""
    if not config.tracking:
        return None
    from training.tracking import log_run

    uri = tracking_uri or config.tracking_uri
    common = {
        "model": config.model,
        "seed": config.seed,
        "test_fraction": config.test_fraction,
        "calibration_fraction": config.calibration_fraction,
        "coverage": config.coverage,
        "data_card_sha256": card_sha,
        "n_windows": n_windows,
    }
    run_id = log_run(
        tracking_uri=uri,
        experiment=config.experiment,
        params={**common, **params},
        metrics=metrics,
        data_card_path=data_dir / CARD,
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
        class_names=names,
        tags={"stiffnet.model": config.model, "stiffnet.data_sha256": card_sha},
        history=history,
        onnx_model=onnx_path,
    )
    say(f"MLflow run {run_id} in {uri} (experiment {config.experiment})")
    return run_id
