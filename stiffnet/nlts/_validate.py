"""Input checks shared by the nlts modules.

Signals that cannot be analysed raise :class:`~stiffnet.errors.SignalError`;
out-of-range parameters (dimension, delay, method names) raise
:class:`~stiffnet.errors.ConfigError`. Both are ``ValueError`` subclasses with a
one-line message that names the problem.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import ConfigError, SignalError


def as_signal(x: ArrayLike, min_len: int, name: str = "signal") -> np.ndarray:
    """Return `x` as a 1-D float64 array fit for analysis.

    Parameters
    ----------
    x : array_like
        Scalar time series.
    min_len : int
        Minimum number of samples the caller needs.
    name : str, optional
        Name used in error messages.

    Returns
    -------
    numpy.ndarray
        1-D float64 array (a copy only when a conversion was needed).

    Raises
    ------
    SignalError
        If `x` is not real and numeric, not 1-D, shorter than `min_len`,
        contains NaN or inf, or is constant.
    """
    if np.iscomplexobj(x):
        raise SignalError(f"{name} is complex; pass the real-valued signal")
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SignalError(f"{name} is not a numeric array ({exc})") from None
    if a.ndim != 1:
        raise SignalError(f"{name} must be 1-D, got an array of shape {a.shape}")
    if a.size < min_len:
        raise SignalError(f"{name} is too short: {a.size} samples, at least {min_len} needed")
    finite = np.isfinite(a)
    if not finite.all():
        n_nan = int(np.isnan(a).sum())
        n_inf = a.size - int(finite.sum()) - n_nan
        raise SignalError(f"{name} contains {n_nan} NaN and {n_inf} inf values")
    # Relative tolerance: a signal whose spread is pure rounding noise is constant.
    if np.ptp(a) <= 8 * np.finfo(np.float64).eps * max(1.0, float(np.abs(a).max())):
        raise SignalError(f"{name} is constant (value {a[0]:g}); nothing to analyse")
    return a


def check_int(value: int, name: str, minimum: int) -> int:
    """Return `value` as an int, raising ConfigError if it is not an integer >= `minimum`."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise ConfigError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise ConfigError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def check_choice(value: str, name: str, choices: Iterable[str]) -> str:
    """Return `value` if it is one of `choices`, else raise ConfigError."""
    choices = tuple(choices)
    if value not in choices:
        raise ConfigError(f"unknown {name} {value!r}; expected one of {', '.join(choices)}")
    return value


def check_curve(curve: ArrayLike, name: str = "curve", min_len: int = 3) -> np.ndarray:
    """Return a finite 1-D float array (a rule's input curve); constant is allowed."""
    c = np.asarray(curve, dtype=np.float64)
    if c.ndim != 1 or c.size < min_len:
        raise SignalError(f"{name} must be 1-D with at least {min_len} values, got shape {c.shape}")
    if not np.isfinite(c).all():
        raise SignalError(f"{name} contains NaN or inf values")
    return c
