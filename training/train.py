"""Train a stiffness model end to end (``stiffnet train``): the gradient-boosting models or,
with ``model: cnn``, the CNN.

:func:`train` picks the family's trainer (:mod:`training.train_gbm`,
:mod:`training.train_cnn`); each loads the dataset, builds its inputs, splits by
trajectory and fits, then runs the tail both share (:mod:`training.finish`):
split-conformal beta interval and alarm, evaluation of the model and the
geometric method (:func:`stiffnet.geometry.geometric_estimate` with the shipped
calibration and its default options) on the same test windows, ONNX export
plus a model card, and the MLflow run.

Run: ``OMP_NUM_THREADS=1 python -m training.train DATA_DIR OUT_DIR [--config FILE.yaml]``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stiffnet.config import load_config
from stiffnet.config.train import TrainConfig
from stiffnet.errors import StiffnetError


def _stderr(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def train(
    data_dir: str | Path,
    config: TrainConfig,
    out_dir: str | Path,
    tracking_uri: str | None = None,
    progress: Callable[[str], None] | None = _stderr,
) -> dict[str, Any]:
    """Train, evaluate, export and track the model ``config.model`` on one dataset.

    Parameters
    ----------
    data_dir : str or Path
        A finished dataset folder (``stiffnet simulate``).
    config : TrainConfig
        Training configuration (``model: gbm`` or ``model: cnn``).
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
        ``metrics`` (flat ``NAME/...`` and ``geometric/...``), ``paths``,
        ``run_id`` (None without tracking), ``conformal_quantile``,
        ``conformal_quantile_recording``, ``parity``, ``timing`` (seconds) and
        the split sizes (see :func:`training.finish.finish_training`).

    Raises
    ------
    StiffnetError
        If the dataset is missing or too small to split.
    """
    if config.model == "cnn":
        from training.train_cnn import train_cnn as family_trainer
    else:
        from training.train_gbm import train_gbm as family_trainer
    return family_trainer(data_dir, config, out_dir, tracking_uri, progress)


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (``stiffnet train`` is the user's)."""
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
