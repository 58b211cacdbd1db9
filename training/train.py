"""Train the gradient-boosting (or, with ``model: cnn``, the CNN) stiffness models end to end
(issue 4).

:func:`train` loads a dataset, extracts inclination features, splits by
trajectory, fits the classifier and the log-beta regressor, calibrates a
split-conformal beta interval, evaluates the models and the geometric method
(:func:`stiffnet.geometry.geometric_estimate` with the shipped calibration and
its default options) on the same test windows, exports ONNX plus a model card
and logs the run to MLflow.

Run: ``OMP_NUM_THREADS=1 python -m training.train DATA_DIR OUT_DIR [--config FILE.yaml]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import sklearn

from stiffnet.config import load_config
from stiffnet.config.train import TrainConfig
from stiffnet.dataset.store import CARD, load_dataset
from stiffnet.errors import SignalError, StiffnetError
from stiffnet.features import FEATURE_NAMES, FEATURE_VERSION
from stiffnet.geometry import geometric_estimate
from stiffnet.io_utils import sha256_file, write_json_atomic
from stiffnet.progress import task as progress_task
from stiffnet.uncertainty.alarm import save_alarm
from training.calibration import calibrate_recording_level
from training.export_onnx import export_onnx, parity
from training.gbm import (
    conformal_quantile,
    confusion,
    evaluate,
    fit_gbm,
    trajectory_split,
)
from training.transformers import InclinationFeatures, window_records

MODEL_FILE = "gbm.onnx"
CNN_MODEL_FILE = "cnn.onnx"
#: The alarm reference sits beside its model: ``cnn.onnx`` -> ``cnn.alarm.npz``.
ALARM_SUFFIX = ".alarm.npz"


def _losses(h: dict[str, float]) -> str:
    return f"epoch {h['epoch']:.0f}: train loss {h['train_loss']:.4f}, val loss {h['val_loss']:.4f}"


def _stderr(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _geometric_chunk(args: tuple[list[np.ndarray], list[float]]) -> list[tuple[str, float]]:
    out = []
    for w, fs in zip(*args, strict=True):
        try:
            r = geometric_estimate(w, fs)
            out.append(
                (str(r.geometric_class), np.nan if r.geometric_beta is None else r.geometric_beta)
            )
        except SignalError:
            out.append(("no_contact", np.nan))
    return out


def geometric_predictions(
    windows: list[np.ndarray], fs_hz: np.ndarray, n_jobs: int = 1
) -> tuple[list[str], np.ndarray]:
    """Class names and betas of the geometric method (shipped calibration, default options).

    A window the method cannot analyse counts as ``no_contact`` with no beta (NaN).
    """
    fs = [float(f) for f in fs_hz]
    n_jobs = (os.cpu_count() or 1) if n_jobs < 0 else n_jobs
    if n_jobs <= 1 or len(windows) < 2:
        rows = _geometric_chunk((windows, fs))
    else:
        b = np.linspace(0, len(windows), 4 * n_jobs + 1).astype(int)
        jobs = [
            (windows[lo:hi], fs[lo:hi]) for lo, hi in zip(b[:-1], b[1:], strict=True) if hi > lo
        ]
        with ProcessPoolExecutor(n_jobs) as pool:
            rows = [r for chunk in pool.map(_geometric_chunk, jobs) for r in chunk]
    return [r[0] for r in rows], np.array([r[1] for r in rows], dtype=np.float64)


def _load(data_dir: Path, say: Callable[[str], None]) -> tuple[Any, list[str], str]:
    """The dataset, its class names and the SHA-256 of its card (the data's identity)."""
    ds = load_dataset(data_dir)
    say(f"dataset {data_dir}: {len(ds)} windows, {ds.card.get('n_trajectories')} trajectories")
    return ds, ds.class_names, sha256_file(data_dir / CARD)


def _split(ds: Any, data_dir: Path, config: TrainConfig, validation_fraction: float,
           say: Callable[[str], None]) -> Any:  # fmt: skip
    """Train / early-stopping / calibration / test windows, split by trajectory."""
    sp = trajectory_split(
        ds.column("trajectory"),
        config.test_fraction,
        config.calibration_fraction,
        validation_fraction,
        config.seed,
    )
    if not (sp.train.any() and sp.test.any() and sp.cal.any()):
        raise StiffnetError(f"dataset {data_dir} has too few trajectories to split")
    say(
        f"split by trajectory: train {sp.train.sum()}, val {sp.val.sum()}, "
        f"calibration {sp.cal.sum()}, test {sp.test.sum()} windows"
    )
    return sp


def _geometric_baseline(accel, fs_hz, label, beta, noise, names, config, metrics, model, say):
    """The geometric method on the same test windows: metrics added under ``geometric/``.

    Returns its class predictions (for the confusion matrix) and the seconds it took.
    """
    t = time.perf_counter()
    g_cls, g_beta = geometric_predictions(accel, fs_hz, config.n_jobs)
    g_pred = np.array([names.index(c) if c in names else 0 for c in g_cls])
    m_geo = evaluate(label, g_pred, beta, g_beta, noise, names, config.noise_bins)
    metrics.update({f"geometric/{k}": v for k, v in m_geo.items()})
    say(
        f"test accuracy: {model} {metrics[f'{model}/accuracy']:.3f}, geometric "
        f"{m_geo['accuracy']:.3f}; beta MAPE: {model} "
        f"{metrics.get(f'{model}/beta_mape', np.nan):.3f}, geometric "
        f"{m_geo.get('beta_mape', np.nan):.3f}"
    )
    return g_pred, time.perf_counter() - t


def _alarm_info(ds: Any, card_sha: str) -> dict[str, Any]:
    """Provenance of the alarm, and the class edges its class-edge check needs."""
    classes = (ds.card.get("config") or {}).get("classes") or []
    edges = [c["beta"][0] for c in classes] + ([classes[-1]["beta"][1]] if classes else [])
    return {"training_data_sha256": card_sha, "class_edges": edges}


def _data_summary(data_dir: Path, card_sha: str, ds: Any) -> dict[str, Any]:
    keys = ("n_trajectories", "seed", "class_balance", "code_version")
    sweep = (ds.card.get("config") or {}).get("sweep") or {}
    return {
        "path": str(data_dir),
        "card_sha256": card_sha,
        "n_windows": len(ds),
        **{k: ds.card.get(k) for k in keys},
        # the rig's f_n in the training data: the predictor's default when a recording
        # comes without one (a number, or the [lo, hi] range it was drawn from)
        "natural_frequency_hz": sweep.get("natural_frequency_hz"),
        # the world the model was trained in: the sweep and each effect's priors
        "priors": {
            "sweep": sweep,
            "effects": (ds.card.get("config") or {}).get("effects") or [],
        },
    }


def _track(config, tracking_uri, data_dir, ds, card_sha, onnx_path, names, say, *, params,
           metrics, confusions, history=None) -> str | None:  # fmt: skip
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
        "n_windows": len(ds),
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


def train(
    data_dir: str | Path,
    config: TrainConfig,
    out_dir: str | Path,
    tracking_uri: str | None = None,
    progress: Callable[[str], None] | None = _stderr,
) -> dict[str, Any]:
    """Train, evaluate, export and track the GBM models on one dataset.

    Parameters
    ----------
    data_dir : str or Path
        A finished dataset folder (``stiffnet simulate``).
    config : TrainConfig
        Training configuration.
    out_dir : str or Path
        Folder for ``gbm.onnx``, ``gbm.card.json`` and ``summary.json`` (created).
    tracking_uri : str or None, optional
        MLflow URI overriding ``config.tracking_uri``; ignored when
        ``config.tracking`` is False.
    progress : callable or None, optional
        Receives one-line progress messages (stderr by default).

    Returns
    -------
    dict
        ``metrics`` (flat ``gbm/...`` and ``geometric/...``), ``paths``,
        ``run_id`` (None without tracking), ``conformal_quantile``,
        ``parity``, ``timing`` (seconds) and the split sizes.

    Raises
    ------
    StiffnetError
        If the dataset is missing or too small to split.
    """
    if config.model == "cnn":
        return train_cnn(data_dir, config, out_dir, tracking_uri, progress)
    say = progress or (lambda _msg: None)
    t0 = time.perf_counter()
    data_dir, out_dir = Path(data_dir), Path(out_dir)
    ds, names, card_sha = _load(data_dir, say)

    t = time.perf_counter()
    recs = window_records(ds)
    feats = InclinationFeatures(config.use_natural_frequency, n_jobs=config.n_jobs)
    X = feats.fit_transform(recs)
    t_feat = time.perf_counter() - t
    say(f"features: {X.shape[1]} per window, {1e3 * t_feat / max(1, len(ds)):.1f} ms/window")

    label, beta, noise = ds.column("label"), ds.column("beta"), ds.column("noise")
    sp = _split(ds, data_dir, config, config.gbm.validation_fraction, say)

    t = time.perf_counter()
    clf, reg = fit_gbm(X, label, beta, sp, config.gbm, config.seed)
    t_fit = time.perf_counter() - t
    say(f"fitted: classifier {clf.n_iter_} iterations, regressor {reg.n_iter_} ({t_fit:.1f} s)")

    contact = label != 0
    cal = sp.cal & contact
    q = conformal_quantile(np.log(beta[cal]) - reg.predict(X[cal]), config.coverage)
    say(f"conformal half-width (log beta, {config.coverage:.0%}): {q:.3f} from {cal.sum()} windows")
    outputs = {"probabilities": clf.predict_proba(X), "log_beta": reg.predict(X)}
    alarm, q_rec, m_rec = calibrate_recording_level(
        ds.column("trajectory"), label, beta, sp, outputs, config.coverage,
        config.alarm_false_alarm, config.seed, _alarm_info(ds, card_sha), config.alarm_checks,
    )  # fmt: skip
    say(f"per-trajectory conformal quantile {q_rec:.3f}; test trajectories: "
        + ", ".join(f"{k} {v:.3f}" for k, v in m_rec.items()))  # fmt: skip

    te = sp.test
    Xt = X[te]
    pred = clf.predict(Xt)
    log_b = reg.predict(Xt)
    metrics: dict[str, float] = {}
    m_gbm = evaluate(
        label[te],
        pred,
        beta[te],
        np.exp(log_b),
        noise[te],
        names,
        config.noise_bins,
        lo=np.exp(log_b - q),
        hi=np.exp(log_b + q),
    )
    metrics.update({f"gbm/{k}": v for k, v in m_gbm.items()})
    metrics.update({f"gbm/recording/{k}": v for k, v in m_rec.items()})

    g_pred, t_geo = _geometric_baseline(
        [np.asarray(recs[i]["accel"]) for i in np.flatnonzero(te)], ds.column("fs_hz")[te],
        label[te], beta[te], noise[te], names, config, metrics, "gbm", say,
    )  # fmt: skip

    out_dir.mkdir(parents=True, exist_ok=True)
    onnx_path = out_dir / MODEL_FILE
    alarm_path = onnx_path.with_suffix(ALARM_SUFFIX)
    save_alarm(alarm_path, alarm)
    data_summary = _data_summary(data_dir, card_sha, ds)
    splits = {k: int(getattr(sp, k).sum()) for k in ("train", "val", "cal", "test")}
    card = export_onnx(
        clf,
        reg,
        FEATURE_NAMES,
        names,
        onnx_path,
        metadata={
            "training_data_sha256": card_sha,
            "conformal_quantile": q,
            "conformal_coverage": config.coverage,
            "feature_version": FEATURE_VERSION,
            "requires_natural_frequency": config.use_natural_frequency,
            "interval": "normalised split-conformal, one score per trajectory",
            "conformal_quantile_recording": q_rec,
            "alarm_reference": alarm_path.name,
            "alarm_sha256": sha256_file(alarm_path),
        },
        card={
            "kind": "stiffnet-model-card",
            "model": "gbm",
            "sklearn_version": sklearn.__version__,
            "config": config.model_dump(mode="json"),
            "data": data_summary,
            "split_windows": splits,
            "metrics": metrics,
            "n_iter": {"classifier": int(clf.n_iter_), "regressor": int(reg.n_iter_)},
        },
    )
    par = parity(onnx_path, clf, reg, Xt if len(Xt) else X)
    say(f"exported {onnx_path} (sha256 {card['sha256'][:12]}); parity {par}")

    run_id = _track(
        config, tracking_uri, data_dir, ds, card_sha, onnx_path, names, say,
        params={
            "use_natural_frequency": config.use_natural_frequency,
            **{f"gbm.{k}": v for k, v in config.gbm.model_dump().items()},
        },
        metrics={**metrics, "conformal_quantile": q,
                 **{f"parity/{k}": v for k, v in par.items()}},
        confusions={
            "gbm": confusion(label[te], pred, len(names)),
            "geometric": confusion(label[te], g_pred, len(names)),
        },
    )  # fmt: skip

    summary = {
        "metrics": metrics,
        "conformal_quantile": q,
        "parity": par,
        "split_windows": splits,
        "run_id": run_id,
        "paths": {
            "onnx": str(onnx_path),
            "card": str(onnx_path.with_suffix(".card.json")),
            "alarm": str(alarm_path),
            "summary": str(out_dir / "summary.json"),
        },
        "conformal_quantile_recording": q_rec,
        "timing": {
            "features_s": round(t_feat, 3),
            "fit_s": round(t_fit, 3),
            "geometric_s": round(t_geo, 3),
            "total_s": round(time.perf_counter() - t0, 3),
        },
    }
    write_json_atomic(out_dir / "summary.json", summary)
    say(f"done in {summary['timing']['total_s']:.1f} s")
    return summary


def train_cnn(
    data_dir: str | Path,
    config: TrainConfig,
    out_dir: str | Path,
    tracking_uri: str | None = None,
    progress: Callable[[str], None] | None = _stderr,
) -> dict[str, Any]:
    """Train, evaluate, export (``cnn.onnx``) and track the 1-D CNN on one dataset.

    Same contract as :func:`train` (which dispatches here for ``model: cnn``):
    canonical windows (:mod:`stiffnet.features.windows`), trajectory-wise split
    with ``config.cnn.validation_fraction``, :func:`training.cnn.fit_cnn`,
    split-conformal log-beta half-width on the calibration trajectories,
    ``cnn/...`` and ``geometric/...`` metrics on the same test windows, ONNX
    export with model card and parity, MLflow run.
    """
    import torch

    from stiffnet.features.windows import WINDOW_VERSION, window_tensor
    from training.cnn import fit_cnn, predict_cnn_outputs
    from training.export_onnx_cnn import TARGET_OPSET, export_cnn_onnx, parity_cnn

    torch.set_num_threads(1)
    say = progress or (lambda _msg: None)
    cc = config.cnn
    t0 = time.perf_counter()
    data_dir, out_dir = Path(data_dir), Path(out_dir)
    ds, names, card_sha = _load(data_dir, say)
    if "natural_frequency_hz" not in ds.table.column_names:
        raise StiffnetError(f"dataset {data_dir} has no natural_frequency_hz: the CNN needs it")

    t = time.perf_counter()
    windows = ds.windows()
    fs_hz = ds.column("fs_hz")
    d = max(1, int(round(cc.delay_fraction * cc.rate)))
    delays = [k * d for k in range(cc.n_channels)]
    X = window_tensor(
        windows, fs_hz, ds.column("natural_frequency_hz"), cc.rate, cc.periods, delays
    )
    t_feat = time.perf_counter() - t
    say(f"canonical windows {X.shape[1:]}, {1e3 * t_feat / max(1, len(ds)):.2f} ms/window")

    label, beta, noise = ds.column("label"), ds.column("beta"), ds.column("noise")
    sp = _split(ds, data_dir, config, cc.validation_fraction, say)

    t = time.perf_counter()
    with progress_task("training epochs", cc.max_epochs) as bar:
        fit = fit_cnn(X, label, beta, sp, len(names), cc, config.seed,
                      on_epoch=lambda h: bar.advance(note=_losses(h)))  # fmt: skip
    t_fit = time.perf_counter() - t
    say(f"fitted: best epoch {fit.best_epoch} of {fit.epochs} ({t_fit:.1f} s)")
    net = fit.model

    outputs = predict_cnn_outputs(net, X)
    contact = label != 0
    cal = sp.cal & contact
    q = conformal_quantile(np.log(beta[cal]) - outputs["log_beta"][cal], config.coverage)
    say(f"conformal half-width (log beta, {config.coverage:.0%}): {q:.3f} from {cal.sum()} windows")
    alarm, q_rec, m_rec = calibrate_recording_level(
        ds.column("trajectory"), label, beta, sp, outputs, config.coverage,
        config.alarm_false_alarm, config.seed, _alarm_info(ds, card_sha), config.alarm_checks,
    )  # fmt: skip
    say(
        f"per-trajectory conformal quantile {q_rec:.3f} (normalised); alarm thresholds "
        f"{ {k: round(v, 4) for k, v in alarm.thresholds.items()} }; test trajectories: "
        + ", ".join(f"{k} {v:.3f}" for k, v in m_rec.items())
    )

    te = sp.test
    Xt = X[te]
    proba, log_b = outputs["probabilities"][te], outputs["log_beta"][te]
    pred = proba.argmax(axis=1) if len(Xt) else np.empty(0, np.int64)
    metrics: dict[str, float] = {}
    m_cnn = evaluate(
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
    metrics.update({f"cnn/{k}": v for k, v in m_cnn.items()})
    metrics.update({f"cnn/recording/{k}": v for k, v in m_rec.items()})

    g_pred, t_geo = _geometric_baseline(
        [np.asarray(windows[i], dtype=np.float64) for i in np.flatnonzero(te)], fs_hz[te],
        label[te], beta[te], noise[te], names, config, metrics, "cnn", say,
    )  # fmt: skip

    out_dir.mkdir(parents=True, exist_ok=True)
    onnx_path = out_dir / CNN_MODEL_FILE
    alarm_path = onnx_path.with_suffix(ALARM_SUFFIX)
    save_alarm(alarm_path, alarm)
    data_summary = _data_summary(data_dir, card_sha, ds)
    splits = {k: int(getattr(sp, k).sum()) for k in ("train", "val", "cal", "test")}
    card = export_cnn_onnx(
        net,
        names,
        onnx_path,
        rate=cc.rate,
        periods=cc.periods,
        delays=delays,
        delay_fraction=cc.delay_fraction,
        metadata={
            "training_data_sha256": card_sha,
            "conformal_quantile": q,
            "conformal_coverage": config.coverage,
            "interval": "normalised split-conformal, one score per trajectory",
            "conformal_quantile_recording": q_rec,
            "alarm_reference": alarm_path.name,
            "alarm_sha256": sha256_file(alarm_path),
        },
        card={
            "kind": "stiffnet-model-card",
            "model": "cnn",
            "torch_version": torch.__version__,
            "config": config.model_dump(mode="json"),
            "data": data_summary,
            "split_windows": splits,
            "metrics": metrics,
            "training": {
                "best_epoch": fit.best_epoch,
                "epochs": fit.epochs,
                "seconds": round(fit.seconds, 3),
                "history": fit.history,
            },
        },
    )
    par = parity_cnn(onnx_path, net, Xt if len(Xt) else X)
    say(f"exported {onnx_path} (sha256 {card['sha256'][:12]}); parity {par}")

    run_id = _track(
        config, tracking_uri, data_dir, ds, card_sha, onnx_path, names, say,
        params={
            "window_version": WINDOW_VERSION,
            "opset": TARGET_OPSET,
            **{f"cnn.{k}": v for k, v in cc.model_dump().items()},
        },
        metrics={**metrics, "conformal_quantile": q, "best_epoch": float(fit.best_epoch),
                 **{f"parity/{k}": v for k, v in par.items()}},
        confusions={
            "cnn": confusion(label[te], pred, len(names)),
            "geometric": confusion(label[te], g_pred, len(names)),
        },
        history=fit.history,
    )  # fmt: skip

    summary = {
        "metrics": metrics,
        "conformal_quantile": q,
        "parity": par,
        "split_windows": splits,
        "run_id": run_id,
        "best_epoch": fit.best_epoch,
        "epochs": fit.epochs,
        "paths": {
            "onnx": str(onnx_path),
            "card": str(onnx_path.with_suffix(".card.json")),
            "alarm": str(alarm_path),
            "summary": str(out_dir / "summary.json"),
        },
        "conformal_quantile_recording": q_rec,
        "timing": {
            "windows_s": round(t_feat, 3),
            "fit_s": round(t_fit, 3),
            "geometric_s": round(t_geo, 3),
            "total_s": round(time.perf_counter() - t0, 3),
        },
    }
    write_json_atomic(out_dir / "summary.json", summary)
    say(f"done in {summary['timing']['total_s']:.1f} s")
    return summary


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (until the ``stiffnet train`` command is wired)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data_dir")
    ap.add_argument("out_dir")
    ap.add_argument("--config", default=None, help="YAML TrainConfig (defaults if omitted)")
    ap.add_argument("--tracking-uri", default=None)
    ap.add_argument("--no-tracking", action="store_true")
    args = ap.parse_args(argv)
    try:
        cfg = load_config(TrainConfig, args.config) if args.config else TrainConfig()
        if args.no_tracking:
            cfg = cfg.model_copy(update={"tracking": False})
        train(args.data_dir, cfg, args.out_dir, tracking_uri=args.tracking_uri)
    except StiffnetError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
