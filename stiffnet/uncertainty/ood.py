"""Out-of-distribution score: how unlike the training windows a recording's windows look.

The reference (``models/ood_reference.json``, fitted by
``training/fit_ood_reference.py`` on the dataset the models were trained on) is a
**class-conditional Gaussian model of the inclination features**
(:func:`stiffnet.features.inclination_features`, the GBM's 23 inputs): the
features are standardised with the training mean and standard deviation, each
class ``c`` gets its mean ``mu_c`` and a shrunk covariance ``S_c``, and a
window's score is its smallest Mahalanobis distance to a class,

``d(x) = min_c sqrt((z - mu_c)^T S_c^-1 (z - mu_c))``,  ``z = (x - center) / scale``.

Per-class rather than one global Gaussian because the feature cloud is a
mixture: windows without contact carry the fill value -1 in every contact
feature, and the four stiffness classes sit at different inclinations. The
shrinkage ``S_c = (1 - a) C_c + a diag(C_c) + e I`` keeps the precision finite
where a feature is constant within a class (the fills).

A recording's score is the **median** of its windows' scores; it is flagged
when it exceeds the threshold stored in the reference: a high percentile (99th
by default) of the per-window scores of *held-out* training trajectories (not
used for the means and covariances). The median of several windows exceeds a
per-window percentile less often than one window does, so the flag's false
alarm rate on in-distribution recordings is at most about 1 %.

Everything here is numpy only (the predictor imports it); the reference is a
plain JSON file, never a pickle.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.errors import StiffnetError
from stiffnet.inputs import read_json

FORMAT = "stiffnet.ood_reference"
VERSION = 1
#: Shrinkage towards the diagonal and ridge (standardised units) of the class covariances.
SHRINKAGE = 0.05
RIDGE = 1e-2


@dataclass(frozen=True)
class OODReference:
    """Class-conditional Gaussian reference of the training features (see the module notes).

    Attributes
    ----------
    feature_names : list of str
        Feature order (must equal :data:`stiffnet.features.FEATURE_NAMES`).
    feature_version : int
        :data:`stiffnet.features.FEATURE_VERSION` at fitting time.
    center, scale : numpy.ndarray
        Standardisation of the features, shape ``(F,)``.
    class_names : list of str
        Classes with a Gaussian.
    means : numpy.ndarray
        Shape ``(C, F)``, standardised class means.
    precisions : numpy.ndarray
        Shape ``(C, F, F)``, inverses of the shrunk class covariances.
    threshold : float
        Score above which a recording is flagged.
    threshold_percentile : float
        Percentile of the held-out window scores that gave `threshold`.
    info : dict
        Everything else in the file (training data SHA-256, natural frequency,
        sampling-rate range, held-out score percentiles...).
    """

    feature_names: list[str]
    feature_version: int
    center: np.ndarray
    scale: np.ndarray
    class_names: list[str]
    means: np.ndarray
    precisions: np.ndarray
    threshold: float
    threshold_percentile: float
    info: dict[str, Any]

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Per-window score: smallest Mahalanobis distance to a class mean.

        Parameters
        ----------
        features : numpy.ndarray
            Shape ``(N, F)`` or ``(F,)``, columns in :attr:`feature_names` order.

        Returns
        -------
        numpy.ndarray
            Shape ``(N,)``, non-negative.
        """
        x = np.atleast_2d(np.asarray(features, dtype=np.float64))
        z = (x - self.center) / self.scale
        diff = z[:, None, :] - self.means[None, :, :]  # (N, C, F)
        d2 = np.einsum("ncf,cfg,ncg->nc", diff, self.precisions, diff)
        return np.sqrt(np.maximum(d2.min(axis=1), 0.0))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready content of the reference file."""
        return {
            "format": FORMAT,
            "version": VERSION,
            "feature_names": list(self.feature_names),
            "feature_version": self.feature_version,
            "center": self.center.tolist(),
            "scale": self.scale.tolist(),
            "class_names": list(self.class_names),
            "means": self.means.tolist(),
            "precisions": self.precisions.tolist(),
            "threshold": self.threshold,
            "threshold_percentile": self.threshold_percentile,
            **self.info,
        }


def fit_reference(
    train: np.ndarray,
    train_labels: np.ndarray,
    heldout: np.ndarray,
    class_names: list[str],
    feature_names: list[str],
    feature_version: int,
    *,
    percentile: float = 99.0,
    info: dict[str, Any] | None = None,
) -> OODReference:
    """Fit the class-conditional reference and calibrate its threshold on held-out windows.

    Parameters
    ----------
    train : numpy.ndarray
        Features of the fitting windows, shape ``(N, F)``.
    train_labels : numpy.ndarray
        Class index of each fitting window (into `class_names`).
    heldout : numpy.ndarray
        Features of windows from other trajectories, for the threshold.
    class_names, feature_names : list of str
        Names of the class indices and of the feature columns.
    feature_version : int
        Version of the feature definitions.
    percentile : float, optional
        Percentile of the held-out scores used as the threshold.
    info : dict, optional
        Extra provenance stored in the file.

    Returns
    -------
    OODReference
    """
    x = np.asarray(train, dtype=np.float64)
    center = x.mean(axis=0)
    scale = x.std(axis=0)
    scale = np.where(scale > 1e-9, scale, 1.0)  # a constant feature: leave it unscaled
    z = (x - center) / scale
    f = x.shape[1]
    names, means, precs = [], [], []
    for c, name in enumerate(class_names):
        zc = z[np.asarray(train_labels) == c]
        if len(zc) < 2 * f:
            continue  # too few windows for a covariance; the other classes cover it
        cov = np.cov(zc, rowvar=False)
        cov = (1 - SHRINKAGE) * cov + SHRINKAGE * np.diag(np.diag(cov)) + RIDGE * np.eye(f)
        names.append(name)
        means.append(zc.mean(axis=0))
        precs.append(np.linalg.inv(cov))
    if not names:
        raise StiffnetError("too few training windows to fit the OOD reference")
    ref = OODReference(
        list(feature_names),
        int(feature_version),
        center,
        scale,
        names,
        np.array(means),
        np.array(precs),
        0.0,
        float(percentile),
        dict(info or {}),
    )
    held = ref.scores(heldout)
    qs = {f"p{q:g}": float(np.percentile(held, q)) for q in (50, 90, 95, 99, 99.9)}
    extra = {**ref.info, "heldout_score_percentiles": qs, "n_heldout_windows": len(held)}
    return OODReference(
        ref.feature_names,
        ref.feature_version,
        center,
        scale,
        names,
        ref.means,
        ref.precisions,
        float(np.percentile(held, percentile)),
        float(percentile),
        extra,
    )


def load_reference(path: str | Path) -> OODReference:
    """Read a reference written by ``training/fit_ood_reference.py``.

    Raises
    ------
    StiffnetError
        If the file is missing, unreadable or not a stiffnet OOD reference.
    """
    path = Path(path)
    if not path.exists():
        raise StiffnetError(f"{path}: OOD reference not found")
    d = read_json(path, "OOD reference")  # bounded, finite, depth-checked (stiffnet.inputs)
    if not isinstance(d, dict) or d.get("format") != FORMAT or d.get("version") != VERSION:
        raise StiffnetError(f"{path}: not a stiffnet OOD reference (format {FORMAT} v{VERSION})")
    try:
        known = {
            "format",
            "version",
            "feature_names",
            "feature_version",
            "center",
            "scale",
            "class_names",
            "means",
            "precisions",
            "threshold",
            "threshold_percentile",
        }
        ref = OODReference(
            feature_names=list(d["feature_names"]),
            feature_version=int(d["feature_version"]),
            center=np.asarray(d["center"], dtype=np.float64),
            scale=np.asarray(d["scale"], dtype=np.float64),
            class_names=list(d["class_names"]),
            means=np.asarray(d["means"], dtype=np.float64),
            precisions=np.asarray(d["precisions"], dtype=np.float64),
            threshold=float(d["threshold"]),
            threshold_percentile=float(d["threshold_percentile"]),
            info={k: v for k, v in d.items() if k not in known},
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise StiffnetError(f"{path}: malformed OOD reference ({exc})") from None
    f = len(ref.feature_names)
    c = len(ref.class_names)
    if ref.means.shape != (c, f) or ref.precisions.shape != (c, f, f) or ref.center.shape != (f,):
        raise StiffnetError(f"{path}: malformed OOD reference (inconsistent shapes)")
    return ref
