"""Train a stiffness model end to end (``stiffnet train``), whatever its family.

:func:`train` loads the dataset, asks the configured family
(:mod:`training.families`) for its inputs, splits by trajectory, lets the family
fit, then runs the tail every family shares (:mod:`training.finish`):
split-conformal beta interval and alarm, evaluation of the model and of the
geometric method (:func:`stiffnet.geometry.geometric_estimate` with the shipped
calibration and its default options) on the same test windows, ONNX export plus a
model card, and the MLflow run.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stiffnet.errors import StiffnetError
from training.config import TrainConfig
from training.finish import finish_training
from training.split import split_windows
from training.training_data import load_training_data


def _stderr(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def train(
    data_dir: str | Path,
    config: TrainConfig,
    out_dir: str | Path,
    tracking_uri: str | None = None,
    progress: Callable[[str], None] | None = _stderr,
) -> dict[str, Any]:
    """Train, evaluate, export and track the model family ``config.model`` on one dataset.

    Parameters
    ----------
    data_dir : str or Path
        A finished dataset folder (``stiffnet simulate``).
    config : TrainConfig
        Training configuration (its ``model`` names the family).
    out_dir : str or Path
        Folder for ``NAME.onnx``, ``NAME.card.json``, ``NAME.alarm.npz`` and
        ``summary.json`` (created).
    tracking_uri : str or None, optional
        MLflow URI overriding ``config.tracking_uri``; ignored when
        ``config.tracking`` is False.
    progress : callable or None, optional
        Receives one-line progress messages (stderr by default).

    Returns
    -------
    dict
        ``metrics`` (``accuracy``, ..., ``recording/...`` and ``geometric/...``),
        ``family``, ``paths``, ``run_id`` (None without tracking),
        ``conformal_quantile``, ``conformal_quantile_recording``, ``parity``,
        ``timing`` (seconds: ``inputs_s``, ``fit_s``, ...) and the split sizes
        (see :func:`training.finish.finish_training`).

    Raises
    ------
    StiffnetError
        If the dataset is missing, lacks what the family needs or is too small to split.
    """
    say = progress or (lambda _msg: None)
    family = config.family
    t0 = time.perf_counter()
    data_dir, out_dir = Path(data_dir), Path(out_dir)
    ds, _, card_sha = load_training_data(data_dir, say)

    t = time.perf_counter()
    try:
        X = family.inputs(ds, config)
    except StiffnetError as exc:
        raise StiffnetError(f"{data_dir}: {exc}") from None
    t_inputs = time.perf_counter() - t
    say(f"{family.name} inputs {X.shape[1:]}, {1e3 * t_inputs / max(1, len(ds)):.2f} ms/window")

    split = split_windows(ds, data_dir, config, config.section.validation_fraction, say)
    t = time.perf_counter()
    model = family.fit(X, ds, split, config, say)
    t_fit = time.perf_counter() - t
    say(f"fitted in {t_fit:.1f} s")
    model.timing = {"inputs_s": t_inputs, "fit_s": t_fit, **model.timing}
    return finish_training(
        model, ds=ds, data_dir=data_dir, out_dir=out_dir, card_sha=card_sha, split=split,
        config=config, tracking_uri=tracking_uri, say=say, started=t0,
    )  # fmt: skip
