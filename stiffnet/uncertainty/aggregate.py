"""One estimate from the windows of a recording (or of a simulated trajectory).

The same function serves calibration (a training trajectory's windows) and
prediction (a recording's windows), so the interval is calibrated on exactly
the quantity it is applied to.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RecordingEstimate:
    """Aggregate of a recording's windows.

    Attributes
    ----------
    probabilities : numpy.ndarray
        Mean class probabilities over the windows, ``(n_classes,)``.
    label : int
        Arg-max of `probabilities`.
    log_beta : float or None
        Mean log beta over the windows whose own class has contact (all windows
        when none has); None when the recording's class is no-contact.
    scale : float or None
        Expected size of the error of `log_beta` (log units):
        ``sqrt(mean(exp(2 s_w)) + var(log_beta_w))`` over the same windows, with
        ``s_w`` the model's per-window scale output (0 when it has none): the
        model's own uncertainty plus the disagreement between windows.
    n_windows : int
        Windows aggregated.
    """

    probabilities: np.ndarray
    label: int
    log_beta: float | None
    scale: float | None
    n_windows: int


def aggregate_windows(
    proba: np.ndarray,
    log_beta: np.ndarray,
    log_scale: np.ndarray | None = None,
    no_contact: int | None = 0,
) -> RecordingEstimate:
    """Mean probabilities, class and log beta with its error scale over windows.

    Parameters
    ----------
    proba : numpy.ndarray
        Per-window class probabilities, ``(n, n_classes)``.
    log_beta : numpy.ndarray
        Per-window log beta, ``(n,)``.
    log_scale : numpy.ndarray, optional
        Per-window log of the expected log-beta error (the CNN's scale head).
        Without it the model's own part of the scale is 1, so the scale only
        grows with the disagreement between windows.
    no_contact : int or None
        Index of the no-contact class (None: the model has none).

    Returns
    -------
    RecordingEstimate
    """
    proba = np.asarray(proba, dtype=np.float64)
    log_beta = np.asarray(log_beta, dtype=np.float64).reshape(-1)
    n = len(proba)
    if n == 0 or log_beta.size != n:
        raise ValueError(f"need one log beta per window, got {log_beta.size} for {n} windows")
    p = proba.mean(axis=0)
    k = int(np.argmax(p))
    if k == no_contact:
        return RecordingEstimate(p, k, None, None, n)
    contact = proba.argmax(axis=1) != no_contact if no_contact is not None else np.ones(n, bool)
    if not contact.any():
        contact = np.ones(n, bool)
    lb = log_beta[contact]
    own = (
        np.ones(lb.size)
        if log_scale is None
        else np.exp(2.0 * np.asarray(log_scale, dtype=np.float64).reshape(-1)[contact])
    )
    scale = float(np.sqrt(own.mean() + lb.var()))
    return RecordingEstimate(p, k, float(lb.mean()), scale, n)
