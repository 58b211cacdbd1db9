"""Fit the predictor's out-of-distribution reference on the models' training dataset.

Computes the inclination features (:func:`stiffnet.features.feature_matrix`,
with each window's natural frequency, as the gradient-boosting family computes
its inputs) of every window of a dataset, splits the trajectories 80/20 (seeded),
fits the class-conditional Gaussian reference of :mod:`stiffnet.uncertainty.ood` on the 80 %
and sets the flag threshold to a percentile (99th by default) of the scores of
the held-out 20 %. Also records the dataset's identity (SHA-256 of its
``card.json``, the value the model cards carry as ``training_data_sha256``),
its natural frequency and its sampling-rate range, which the predictor uses as
the fallback natural frequency and for range warnings.

Library use (about a minute on one core for the 8,000 default windows)::

    OMP_NUM_THREADS=1 python -c "from training.fit_ood_reference import fit;
        fit('data/train4k', 'models/ood_reference.json')"
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from stiffnet.config.window import WINDOW_PERIODS
from stiffnet.dataset.store import CARD, load_dataset
from stiffnet.features import FEATURE_NAMES, FEATURE_VERSION, feature_matrix
from stiffnet.io_utils import sha256_file, write_json_atomic
from stiffnet.uncertainty.ood import fit_reference


def fit(
    data_dir: str | Path,
    out: str | Path,
    *,
    percentile: float = 99.0,
    heldout_fraction: float = 0.2,
    seed: int = 0,
    n_jobs: int = 1,
    max_windows: int | None = None,
    say: Callable[[str], None] = print,
) -> dict:
    """Fit and write the reference; returns its content (see the module notes)."""
    data_dir = Path(data_dir)
    ds = load_dataset(data_dir)
    n = len(ds)
    idx = np.arange(n)
    if max_windows is not None and max_windows < n:
        idx = np.sort(np.random.default_rng(seed).choice(n, max_windows, replace=False))
    windows = ds.windows()
    fs = ds.column("fs_hz")[idx]
    fn = ds.column("natural_frequency_hz")[idx]
    t = time.perf_counter()
    X = feature_matrix([windows[i] for i in idx], fs, fn, n_jobs=n_jobs)
    seconds = time.perf_counter() - t
    labels = ds.column("label")[idx]
    traj = ds.column("trajectory")[idx]
    uniq = np.unique(traj)
    rng = np.random.default_rng(seed)
    held_traj = rng.choice(uniq, max(1, int(round(heldout_fraction * uniq.size))), replace=False)
    held = np.isin(traj, held_traj)
    fs_ratio = fs / fn
    info = {
        "training_data_sha256": sha256_file(data_dir / CARD),
        "data_path": str(data_dir),
        "natural_frequency_hz": float(np.median(fn)),
        "natural_frequency_range_hz": [float(fn.min()), float(fn.max())],
        "fs_ratio_range": [float(fs_ratio.min()), float(fs_ratio.max())],
        "window_periods": float(
            ds.card.get("config", {}).get("windows", {}).get("duration_periods", WINDOW_PERIODS)
        ),
        "n_fit_windows": int((~held).sum()),
        "seed": seed,
        "method": "class-conditional Gaussians on standardised inclination features "
        "(shrunk covariances); score = min Mahalanobis distance; recording = median of windows",
        "script": "training/fit_ood_reference.py",
    }
    ref = fit_reference(
        X[~held],
        labels[~held],
        X[held],
        ds.class_names,
        FEATURE_NAMES,
        FEATURE_VERSION,
        percentile=percentile,
        info=info,
    )
    content = ref.to_dict()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out, content)
    say(
        f"features of {len(idx)} windows in {seconds:.1f} s; threshold (p{percentile:g} of "
        f"{int(held.sum())} held-out windows) = {ref.threshold:.3f}; written to {out}"
    )
    return content
