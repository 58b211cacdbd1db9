"""The geometric method as the learned models' baseline, on the same test windows.

:func:`stiffnet.geometry.geometric_estimate` with the shipped calibration and
its default options; a window the method cannot analyse counts as
``no_contact`` with no beta.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from stiffnet.errors import SignalError
from stiffnet.geometry import geometric_estimate
from training.config import TrainConfig
from training.metrics import evaluate


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


def geometric_baseline(
    windows: list[np.ndarray],
    fs_hz: np.ndarray,
    label: np.ndarray,
    beta: np.ndarray,
    noise: np.ndarray,
    names: list[str],
    config: TrainConfig,
    metrics: dict[str, float],
    model: str,
    say: Callable[[str], None],
) -> tuple[np.ndarray, float]:
    """The geometric method on the test windows: metrics added under ``geometric/``.

    Returns its class predictions (for the confusion matrix) and the seconds it took.
    """
    t = time.perf_counter()
    g_cls, g_beta = geometric_predictions(windows, fs_hz, config.n_jobs)
    g_pred = np.array([names.index(c) if c in names else 0 for c in g_cls])
    m_geo = evaluate(label, g_pred, beta, g_beta, noise, names, config.noise_bins)
    metrics.update({f"geometric/{k}": v for k, v in m_geo.items()})
    say(
        f"test accuracy: {model} {metrics['accuracy']:.3f}, geometric "
        f"{m_geo['accuracy']:.3f}; beta MAPE: {model} "
        f"{metrics.get('beta_mape', np.nan):.3f}, geometric "
        f"{m_geo.get('beta_mape', np.nan):.3f}"
    )
    return g_pred, time.perf_counter() - t
