"""Train the 1-D CNN end to end: canonical windows, fit, shared tail.

:func:`train_cnn` loads a dataset (it needs each window's natural frequency),
turns every window into the CNN's canonical delay-embedded input
(:func:`stiffnet.features.windows.window_tensor`), splits by trajectory, fits
the network (:func:`training.cnn.fit_cnn`) and hands it to the tail both
families share (:func:`training.finish.finish_training`: interval and alarm
calibration, metrics against the geometric method, ONNX export with card and
parity, MLflow).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch

from stiffnet.config.train import TrainConfig
from stiffnet.errors import StiffnetError
from stiffnet.features.windows import WINDOW_VERSION, default_delays, window_tensor
from stiffnet.progress import task as progress_task
from training.cnn import fit_cnn, predict_cnn_outputs
from training.export_onnx_cnn import TARGET_OPSET, export_cnn_onnx, parity_cnn
from training.finish import TrainedModel, finish_training
from training.split import split_windows
from training.training_data import load_training_data


def _losses(h: dict[str, float]) -> str:
    return f"epoch {h['epoch']:.0f}: train loss {h['train_loss']:.4f}, val loss {h['val_loss']:.4f}"


def train_cnn(
    data_dir: str | Path,
    config: TrainConfig,
    out_dir: str | Path,
    tracking_uri: str | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Train, evaluate, export (``cnn.onnx``) and track the 1-D CNN on one dataset.

    Same contract as :func:`training.train.train` (which dispatches here for
    ``model: cnn``); the split uses ``config.cnn.validation_fraction``, the
    summary adds ``best_epoch`` and ``epochs`` and its ``timing`` has
    ``windows_s`` and ``fit_s``.
    """
    torch.set_num_threads(1)
    say = progress or (lambda _msg: None)
    cc = config.cnn
    t0 = time.perf_counter()
    data_dir, out_dir = Path(data_dir), Path(out_dir)
    ds, names, card_sha = load_training_data(data_dir, say)
    if "natural_frequency_hz" not in ds.table.column_names:
        raise StiffnetError(f"dataset {data_dir} has no natural_frequency_hz: the CNN needs it")

    t = time.perf_counter()
    delays = list(default_delays(cc.rate, cc.n_channels, cc.delay_fraction))
    X = window_tensor(
        ds.windows(), ds.column("fs_hz"), ds.column("natural_frequency_hz"), cc.rate, cc.periods,
        delays,
    )  # fmt: skip
    t_win = time.perf_counter() - t
    say(f"canonical windows {X.shape[1:]}, {1e3 * t_win / max(1, len(ds)):.2f} ms/window")

    label, beta = ds.column("label"), ds.column("beta")
    sp = split_windows(ds, data_dir, config, cc.validation_fraction, say)

    t = time.perf_counter()
    with progress_task("training epochs", cc.max_epochs) as bar:
        fit = fit_cnn(X, label, beta, sp, len(names), cc, config.seed,
                      on_epoch=lambda h: bar.advance(note=_losses(h)))  # fmt: skip
    t_fit = time.perf_counter() - t
    say(f"fitted: best epoch {fit.best_epoch} of {fit.epochs} ({t_fit:.1f} s)")
    net = fit.model

    model = TrainedModel(
        name="cnn",
        inputs=X,
        outputs=predict_cnn_outputs(net, X),
        classes=np.arange(len(names)),
        export=lambda path, metadata, card: export_cnn_onnx(
            net,
            names,
            path,
            rate=cc.rate,
            periods=cc.periods,
            delays=delays,
            delay_fraction=cc.delay_fraction,
            metadata=metadata,
            card=card,
        ),  # fmt: skip
        parity=lambda path, rows: parity_cnn(path, net, rows),
        versions={"torch_version": torch.__version__},
        card={
            "training": {
                "best_epoch": fit.best_epoch,
                "epochs": fit.epochs,
                "seconds": round(fit.seconds, 3),
                "history": fit.history,
            }
        },
        params={
            "window_version": WINDOW_VERSION,
            "opset": TARGET_OPSET,
            **{f"cnn.{k}": v for k, v in cc.model_dump().items()},
        },
        metrics={"best_epoch": float(fit.best_epoch)},
        summary={"best_epoch": fit.best_epoch, "epochs": fit.epochs},
        timing={"windows_s": t_win, "fit_s": t_fit},
        history=fit.history,
    )
    return finish_training(
        model, ds=ds, data_dir=data_dir, out_dir=out_dir, card_sha=card_sha, split=sp,
        config=config, tracking_uri=tracking_uri, say=say, started=t0,
    )  # fmt: skip
