"""The 1-D CNN family's training steps: canonical windows in, one network out.

:func:`cnn_inputs` turns every window into the CNN's canonical delay-embedded
input (:func:`stiffnet.features.windows.window_tensor`; it needs each window's
natural frequency); :func:`fit_cnn_family` fits the network
(:func:`training.families.cnn.network.fit_cnn`) and hands it to the tail every
family shares (:func:`training.finish.finish_training`: interval and alarm
calibration, metrics against the geometric method, ONNX export with card and
parity, MLflow) as a :class:`~training.families.base.TrainedModel`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from stiffnet.errors import StiffnetError
from stiffnet.features.windows import WINDOW_VERSION, default_delays, window_tensor
from stiffnet.progress import task as progress_task
from training.config import TrainConfig
from training.families.base import TrainedModel
from training.families.cnn.export import TARGET_OPSET, export_cnn_onnx, parity_cnn
from training.families.cnn.network import fit_cnn, predict_cnn_outputs
from training.split import Split


def _losses(h: dict[str, float]) -> str:
    return f"epoch {h['epoch']:.0f}: train loss {h['train_loss']:.4f}, val loss {h['val_loss']:.4f}"


def cnn_inputs(
    ds: Any, rate: int, periods: int, delays: list[int], where: object = "dataset"
) -> np.ndarray:
    """The canonical delay-embedded input of every window of `ds`, ``(N, C, rate * periods)``."""
    if "natural_frequency_hz" not in ds.table.column_names:
        raise StiffnetError(f"{where} has no natural_frequency_hz: the CNN needs it")
    fs, fn = ds.column("fs_hz"), ds.column("natural_frequency_hz")
    return window_tensor(ds.windows(), fs, fn, rate, periods, delays)


def config_delays(config: TrainConfig) -> list[int]:
    """The channel delays in canonical samples of the config's CNN section."""
    cc = config.section
    return list(default_delays(cc.rate, cc.n_channels, cc.delay_fraction))


def fit_cnn_family(
    X: np.ndarray, ds: Any, split: Split, config: TrainConfig, say: Callable[[str], None]
) -> TrainedModel:
    """Fit the network on the ``train`` rows; the model and its hooks."""
    torch.set_num_threads(1)
    cc, names, delays = config.section, ds.class_names, config_delays(config)
    with progress_task("training epochs", cc.max_epochs) as bar:
        fit = fit_cnn(X, ds.column("label"), ds.column("beta"), split, len(names), cc,
                      config.seed, on_epoch=lambda h: bar.advance(note=_losses(h)))  # fmt: skip
    say(f"fitted: best epoch {fit.best_epoch} of {fit.epochs}")
    net = fit.model
    return TrainedModel(
        name=str(config.model),
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
            **{f"{config.model}.{k}": v for k, v in cc.model_dump().items()},
        },
        metrics={"best_epoch": float(fit.best_epoch)},
        summary={"best_epoch": fit.best_epoch, "epochs": fit.epochs},
        history=fit.history,
    )
