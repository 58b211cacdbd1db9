"""The trajectory-wise split of a dataset's windows: train, validation, calibration, test.

Whole trajectories go to one part, so windows of one trajectory (consecutive,
strongly correlated) never straddle training and evaluation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.errors import StiffnetError
from training.config import TrainConfig


@dataclass(frozen=True)
class Split:
    """Boolean window masks of a trajectory-wise split."""

    train: np.ndarray
    val: np.ndarray
    cal: np.ndarray
    test: np.ndarray


def trajectory_split(
    trajectory: np.ndarray,
    test_fraction: float,
    calibration_fraction: float,
    validation_fraction: float,
    seed: int,
) -> Split:
    """Split windows by trajectory into train, validation, calibration and test.

    Parameters
    ----------
    trajectory : numpy.ndarray
        Trajectory id of each window.
    test_fraction, calibration_fraction : float
        Fractions of all trajectories for test and conformal calibration.
    validation_fraction : float
        Fraction of the remaining (training) trajectories kept for early stopping.
    seed : int
        Seed of the trajectory permutation.

    Returns
    -------
    Split
        Disjoint masks covering every window; each part gets at least one
        trajectory when there are at least four.
    """
    ids = np.unique(trajectory)
    perm = np.random.default_rng(seed).permutation(ids)
    n = ids.size
    n_test = max(1, int(round(test_fraction * n))) if n >= 4 else 0
    n_cal = max(1, int(round(calibration_fraction * n))) if n >= 4 else 0
    n_rest = n - n_test - n_cal
    n_val = max(1, int(round(validation_fraction * n_rest))) if n_rest >= 2 else 0
    parts = np.split(perm, np.cumsum([n_test, n_cal, n_val]))
    test, cal, val, train = (np.isin(trajectory, p) for p in parts)
    return Split(train=train, val=val, cal=cal, test=test)


def split_windows(
    ds: Any,
    data_dir: Path,
    config: TrainConfig,
    validation_fraction: float,
    say: Callable[[str], None],
) -> Split:
    """The training split of a dataset (seed and fractions from `config`), reported.

    Raises
    ------
    StiffnetError
        If a part needed for training, calibration or testing is empty.
    """
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
