"""Calibration from inclinations to a stiffness ratio and class (paper section 5.2, Fig. 11).

The paper reads beta off the trend of the coloured map "inclination before vs
after impact"; here that trend is fitted on simulated windows:

* features: the two mean inclinations are turned into log-gradients,
  ``u = log10(tan(theta))``. Both angles crowd towards 90 degrees as beta
  grows (Fig. 11: "the difference ... became very minor"), where a polynomial
  in degrees would need huge coefficients; the log-gradient spreads that end
  out again (89.5 deg -> 2.06, 89.8 deg -> 2.46) and is a smooth function of
  the spike shape.
* model: ordinary least squares of ``log(beta)`` on a full polynomial of total
  degree ``degree`` (the shipped file: 3, ten coefficients) in the two
  standardised log-gradients. Features are clipped to the range seen in
  training and estimates to the training range of beta, so the polynomial is
  never extrapolated.
* orbit: the "before" angle reads the orbit as well as beta
  (:mod:`stiffnet.geometry.orbit`), so a calibration holds one map for period-1
  windows (one impact per forcing period, the paper's Table 1) and, optionally,
  a second one (``period_n``) fitted on the windows of every other orbit (several
  impacts per period, one every few periods, no repeating pattern);
  :meth:`GeometricCalibration.for_orbit` picks it. Files without ``period_n``
  (version 1) use their one map for every orbit.
* class: the class whose beta interval contains the estimate (the nearest
  interval for estimates outside 5-100) - the nearest-class rule on the beta
  axis. A window without contact gives ``"no_contact"`` and beta NaN.

The fitted model is a small JSON file (:func:`save_calibration`,
:func:`load_calibration`) holding the coefficients, the simulation settings,
the fit residuals and the validity domain; ``training/fit_geometric_calibration.py``
writes ``models/geometric_calibration.json``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import ConfigError
from stiffnet.geometry.inclination import check_method
from stiffnet.shipped import REPO_MODELS_DIR, shipped_file

#: Stiffness classes (name, lowest beta, highest beta); the last is closed on the right.
DEFAULT_CLASSES: tuple[tuple[str, float, float], ...] = (
    ("soft", 5.0, 15.0),
    ("medium", 15.0, 35.0),
    ("hard", 35.0, 60.0),
    ("very_hard", 60.0, 100.0),
)
NO_CONTACT = "no_contact"
FORMAT = "stiffnet.geometric_calibration"
VERSION = 2
#: File name of the shipped calibration in ``models/``.
CALIBRATION_FILE = "geometric_calibration.json"
#: The shipped calibration of the source checkout (where the fitting script writes it).
DEFAULT_CALIBRATION_PATH = REPO_MODELS_DIR / CALIBRATION_FILE

# Angles are clipped into (0, 90) before tan(): 1e-3 deg from either end.
_ANGLE_EPS = 1e-3


def log_gradient(theta_deg: ArrayLike) -> np.ndarray:
    """``log10(tan(theta))`` of inclinations in degrees, clipped just inside (0, 90)."""
    t = np.clip(np.asarray(theta_deg, dtype=np.float64), _ANGLE_EPS, 90.0 - _ANGLE_EPS)
    return np.log10(np.tan(np.radians(t)))


def _exponents(degree: int) -> list[tuple[int, int]]:
    """Monomials ``u1**i * u2**j`` with ``i + j <= degree``, in a fixed order."""
    return [(i, t - i) for t in range(degree + 1) for i in range(t, -1, -1)]


def _design(z: np.ndarray, degree: int) -> np.ndarray:
    return np.stack([z[:, 0] ** i * z[:, 1] ** j for i, j in _exponents(degree)], axis=1)


def beta_class(beta: ArrayLike, classes: Sequence[Sequence[Any]] = DEFAULT_CLASSES) -> np.ndarray:
    """Nearest-class rule: the class whose beta interval contains `beta`, else the nearest one.

    Parameters
    ----------
    beta : array_like
        Stiffness ratios; NaN gives ``"no_contact"``.
    classes : sequence of (name, low, high)
        Contiguous intervals ``[low, high)`` in increasing order.

    Returns
    -------
    numpy.ndarray
        Class names (object array of str), same shape as `beta`.
    """
    b = np.asarray(beta, dtype=np.float64)
    names = np.array([c[0] for c in classes] + [NO_CONTACT], dtype=object)
    inner = np.array([float(c[1]) for c in classes[1:]])
    idx = np.searchsorted(inner, np.nan_to_num(b, nan=0.0), side="right")
    idx = np.where(np.isnan(b), len(classes), idx)
    return names[idx]


@dataclass(frozen=True)
class GeometricCalibration:
    """A fitted map (inclination before, inclination after) -> beta and class.

    Attributes
    ----------
    method : str
        Inclination estimator the features come from (``"polynomial"`` or ``"gradient"``).
    degree : int
        Total degree of the polynomial in the two log-gradients.
    coefficients : list of float
        Coefficients of ``log(beta)``, monomials ordered as ``_exponents(degree)``.
    feature_mean, feature_scale : list of float
        Standardisation of the two log-gradients (before, after).
    feature_low, feature_high : list of float
        Training range of the raw log-gradients; inputs are clipped to it.
    beta_low, beta_high : float
        Training range of beta; estimates are clipped to it.
    classes : list of [name, low, high]
        Stiffness classes.
    simulation : dict
        How the training windows were simulated and processed.
    residuals : dict
        Fit quality (training and held-out).
    validity : str
        The domain in which the calibration was fitted and checked.
    period_n : GeometricCalibration or None
        The map for windows that are not on the period-1 orbit (None: this one
        serves every orbit).
    version : int
        File format version.
    """

    method: str
    degree: int
    coefficients: list[float]
    feature_mean: list[float]
    feature_scale: list[float]
    feature_low: list[float]
    feature_high: list[float]
    beta_low: float = 5.0
    beta_high: float = 100.0
    classes: list[list[Any]] = field(default_factory=lambda: [list(c) for c in DEFAULT_CLASSES])
    simulation: dict[str, Any] = field(default_factory=dict)
    residuals: dict[str, Any] = field(default_factory=dict)
    validity: str = ""
    period_n: GeometricCalibration | None = None
    version: int = VERSION

    def for_orbit(self, pattern: Sequence[int] | None) -> GeometricCalibration:
        """The map for windows with impact pattern `pattern` (``(1, 1)``: period-1).

        Period-1 windows get this calibration; any other pattern (or None: no
        repeating pattern) gets :attr:`period_n` when the file has one.
        """
        if self.period_n is None or (pattern is not None and tuple(pattern) == (1, 1)):
            return self
        return self.period_n

    def features(self, before_deg: ArrayLike, after_deg: ArrayLike) -> np.ndarray:
        """Standardised, clipped log-gradients, shape (N, 2)."""
        u = np.stack(
            [np.atleast_1d(log_gradient(before_deg)), np.atleast_1d(log_gradient(after_deg))],
            axis=1,
        )
        u = np.clip(u, self.feature_low, self.feature_high)
        return (u - np.asarray(self.feature_mean)) / np.asarray(self.feature_scale)

    def predict_beta(self, before_deg: ArrayLike, after_deg: ArrayLike) -> np.ndarray:
        """Estimated beta for each (before, after) pair; NaN where an angle is NaN."""
        b = np.atleast_1d(np.asarray(before_deg, dtype=np.float64))
        a = np.atleast_1d(np.asarray(after_deg, dtype=np.float64))
        ok = np.isfinite(b) & np.isfinite(a)
        out = np.full(np.broadcast(b, a).shape, np.nan)
        if ok.any():
            bb, aa = np.broadcast_arrays(b, a)
            z = self.features(bb[ok], aa[ok])
            log_beta = _design(z, self.degree) @ np.asarray(self.coefficients)
            out[ok] = np.clip(np.exp(log_beta), self.beta_low, self.beta_high)
        return out

    def predict(self, angles: ArrayLike) -> tuple[Any, Any]:
        """Beta and class from inclinations ``(before, after)`` in degrees.

        Parameters
        ----------
        angles : array_like
            One pair ``(before, after)`` or an array of shape (N, 2). A NaN
            angle (no contact in the window) gives beta NaN and ``"no_contact"``.

        Returns
        -------
        beta, cls
            A float and a str for one pair; arrays of shape (N,) otherwise.
        """
        arr = np.asarray(angles, dtype=np.float64)
        single = arr.ndim == 1
        arr = np.atleast_2d(arr)
        if arr.shape[-1] != 2 or arr.ndim != 2:
            raise ConfigError(f"angles must be (before, after) or shape (N, 2), got {arr.shape}")
        beta = self.predict_beta(arr[:, 0], arr[:, 1])
        cls = beta_class(beta, self.classes)
        if single:
            return float(beta[0]), str(cls[0])
        return beta, cls

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        return {"format": FORMAT, **d}


def fit_calibration(
    before_deg: ArrayLike,
    after_deg: ArrayLike,
    beta: ArrayLike,
    degree: int = 2,
    method: str = "polynomial",
    classes: Sequence[Sequence[Any]] = DEFAULT_CLASSES,
    simulation: dict[str, Any] | None = None,
    validity: str = "",
) -> GeometricCalibration:
    """Least-squares fit of ``log(beta)`` on a polynomial in the two log-gradients.

    Parameters
    ----------
    before_deg, after_deg : array_like
        Mean inclinations of training windows (degrees); windows with a NaN
        angle are ignored.
    beta : array_like
        True stiffness ratios of those windows.
    degree : int, optional
        Total polynomial degree (1: plane, 2: quadratic, 3: cubic).
    method : str, optional
        Inclination estimator the angles come from (recorded).
    classes : sequence of (name, low, high), optional
        Stiffness classes for the class rule.
    simulation : dict, optional
        Settings of the simulated training data (recorded).
    validity : str, optional
        Validity domain (recorded).

    Returns
    -------
    GeometricCalibration
        With ``residuals`` holding the training RMS error of ``log(beta)``,
        the median absolute percentage error of beta and the class accuracy.
    """
    check_method(method)
    if not isinstance(degree, int) or not 1 <= degree <= 4:
        raise ConfigError(f"degree must be an integer in 1..4, got {degree!r}")
    b = np.asarray(before_deg, dtype=np.float64)
    a = np.asarray(after_deg, dtype=np.float64)
    y = np.asarray(beta, dtype=np.float64)
    if not (b.shape == a.shape == y.shape) or b.ndim != 1:
        raise ConfigError("before, after and beta must be 1-D arrays of the same length")
    ok = np.isfinite(b) & np.isfinite(a) & np.isfinite(y) & (y > 0)
    n_terms = len(_exponents(degree))
    if ok.sum() < 3 * n_terms:
        raise ConfigError(
            f"{int(ok.sum())} usable windows are too few for degree {degree} ({3 * n_terms} needed)"
        )
    u = np.stack([log_gradient(b[ok]), log_gradient(a[ok])], axis=1)
    mean, scale = u.mean(axis=0), u.std(axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    design = _design((u - mean) / scale, degree)
    coef, *_ = np.linalg.lstsq(design, np.log(y[ok]), rcond=None)
    cal = GeometricCalibration(
        method=method,
        degree=degree,
        coefficients=[float(c) for c in coef],
        feature_mean=[float(v) for v in mean],
        feature_scale=[float(v) for v in scale],
        feature_low=[float(v) for v in u.min(axis=0)],
        feature_high=[float(v) for v in u.max(axis=0)],
        beta_low=float(y[ok].min()),
        beta_high=float(y[ok].max()),
        classes=[[str(c[0]), float(c[1]), float(c[2])] for c in classes],
        simulation=dict(simulation or {}),
        validity=validity,
    )
    res = calibration_errors(cal, b[ok], a[ok], y[ok])
    return GeometricCalibration(**{**asdict(cal), "residuals": {"train": res}})


def calibration_errors(
    cal: GeometricCalibration, before_deg: ArrayLike, after_deg: ArrayLike, beta: ArrayLike
) -> dict[str, float]:
    """Accuracy of `cal` on windows with known beta (all of them with contact).

    Returns
    -------
    dict
        ``n``; ``rmse_log_beta`` (natural log); ``mape_beta`` and
        ``median_ape_beta`` (percent); ``class_accuracy`` (fraction); windows
        whose angles are NaN count as wrong class and are left out of the
        beta errors (``n_missing``).
    """
    return beta_errors(cal.predict_beta(before_deg, after_deg), beta, cal.classes)


def beta_errors(
    pred: ArrayLike, beta: ArrayLike, classes: Sequence[Sequence[Any]] = DEFAULT_CLASSES
) -> dict[str, float]:
    """Errors of estimated betas `pred` (NaN: no estimate) against the true `beta`.

    Returns
    -------
    dict
        As :func:`calibration_errors`.
    """
    y = np.asarray(beta, dtype=np.float64)
    pred = np.asarray(pred, dtype=np.float64)
    ok = np.isfinite(pred)
    err = np.log(pred[ok]) - np.log(y[ok])
    ape = 100.0 * np.abs(pred[ok] - y[ok]) / y[ok]
    cls_true = beta_class(y, classes)
    cls_pred = beta_class(pred, classes)
    nan = float("nan")
    return {
        "n": int(y.size),
        "n_missing": int((~ok).sum()),
        "rmse_log_beta": float(np.sqrt(np.mean(err**2))) if ok.any() else nan,
        "mape_beta": float(np.mean(ape)) if ok.any() else nan,
        "median_ape_beta": float(np.median(ape)) if ok.any() else nan,
        "class_accuracy": float(np.mean(cls_true == cls_pred)) if y.size else nan,
    }


def _clean(obj: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python, NaN/inf to None."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    if isinstance(obj, np.generic):
        return _clean(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def save_calibration(cal: GeometricCalibration, path: str | Path) -> Path:
    """Write `cal` as JSON (atomically: a temporary file renamed into place)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(_clean(cal.to_dict()), indent=1) + "\n")
    tmp.replace(path)
    return path


def load_calibration(path: str | Path | None = None) -> GeometricCalibration:
    """Read a calibration written by :func:`save_calibration` (default: the shipped one,
    :func:`stiffnet.shipped.shipped_file`).

    Raises
    ------
    ConfigError
        If the file is missing, not a stiffnet calibration, or of a newer version.
    """
    path = shipped_file(CALIBRATION_FILE) if path is None else Path(path)
    try:
        d = json.loads(path.read_text())
    except FileNotFoundError:
        raise ConfigError(
            f"geometric calibration not found: {path} (run training/fit_geometric_calibration.py)"
        ) from None
    except (OSError, json.JSONDecodeError) as exc:
        raise ConfigError(f"cannot read geometric calibration {path}: {exc}") from None
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ConfigError(f"{path} is not a stiffnet geometric calibration")
    if int(d.get("version", 0)) > VERSION:
        raise ConfigError(
            f"{path} has calibration version {d['version']}; this stiffnet reads up to {VERSION}"
        )
    d.pop("format")
    return _from_dict(d, path)


def _from_dict(d: dict[str, Any], path: Path) -> GeometricCalibration:
    sub = d.pop("period_n", None)
    try:
        cal = GeometricCalibration(**d)
    except TypeError as exc:
        raise ConfigError(f"{path}: malformed calibration ({exc})") from None
    check_method(cal.method)
    if len(cal.coefficients) != len(_exponents(cal.degree)):
        raise ConfigError(f"{path}: {len(cal.coefficients)} coefficients for degree {cal.degree}")
    if sub is not None:
        if not isinstance(sub, dict):
            raise ConfigError(f"{path}: malformed calibration (period_n is not a mapping)")
        inner = _from_dict(dict(sub), path)
        if inner.method != cal.method or inner.period_n is not None:
            raise ConfigError(f"{path}: period_n must be a plain {cal.method} calibration")
        cal = replace(cal, period_n=inner)
    return cal
