"""The unreliability alarm: checks on what the model looks at, calibrated in distribution.

A learned model is confidently wrong where its input is unlike its training
data; an OOD score on hand-made features can miss that, because the model does
not look at those features. The checks here look at the model itself:

``embedding``
    distance of the recording's windows to the training windows *in the
    model's own embedding* (the pooled features its heads read): the mean
    Euclidean distance of a window's standardised embedding to its ``k``
    nearest training embeddings (a k-NN novelty score, cKDTree), the median
    over the recording's windows.
``ambiguity``
    ``1 - max`` of the mean class probabilities: the model itself cannot decide.
``beta_uncertainty``
    the scale of the recording's log-beta error (:mod:`~stiffnet.uncertainty.aggregate`):
    the model's own error estimate plus the disagreement between windows.
``class_edge``
    how close the beta estimate sits to a class edge, in units of its own error
    scale (``scale / |log beta - log edge|`` for the nearest interior edge): the
    class is a coin toss there, which is where an in-distribution model errs.

Each check has a threshold; a recording is flagged when any check exceeds
its threshold, and the result says which fired. The thresholds come from
in-distribution trajectories held out of training (the calibration split):
:func:`calibrate_thresholds` raises one common percentile of every check until
at most ``target`` of those trajectories would be flagged, so the alarm's false
alarm rate on recordings like the training data is about ``target``.

The reference is a ``.npz`` of plain arrays (loaded with ``allow_pickle=False``)
with its metadata as a JSON string.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.errors import StiffnetError

FORMAT = "stiffnet.alarm_reference"
VERSION = 1
#: Neighbours of the k-NN embedding distance.
K_NEIGHBOURS = 10
#: Default fraction of in-distribution recordings the alarm may flag.
TARGET_FALSE_ALARM = 0.04
#: Order in which the checks are reported.
CHECKS = ("embedding", "ambiguity", "beta_uncertainty", "class_edge", "features")


@dataclass
class AlarmReference:
    """Training embeddings and the thresholds of each check (see the module notes).

    Attributes
    ----------
    thresholds : dict
        Check name -> threshold (a check without a threshold is not used).
    embeddings : numpy.ndarray or None
        Standardised training embeddings ``(M, D)`` for the ``embedding`` check.
    center, scale : numpy.ndarray or None
        Standardisation of the embeddings, ``(D,)``.
    k : int
        Neighbours of the k-NN distance.
    info : dict
        Provenance (training data SHA-256, model SHA-256, calibration rates).
    """

    thresholds: dict[str, float]
    embeddings: np.ndarray | None = None
    center: np.ndarray | None = None
    scale: np.ndarray | None = None
    k: int = K_NEIGHBOURS
    info: dict[str, Any] = field(default_factory=dict)
    _tree: Any = field(default=None, repr=False, compare=False)

    def embedding_scores(self, embedding: np.ndarray) -> np.ndarray:
        """Per-window mean distance to the ``k`` nearest training embeddings, ``(n,)``."""
        if self.embeddings is None:
            raise StiffnetError("the alarm reference has no training embeddings")
        if self._tree is None:
            from scipy.spatial import cKDTree

            self._tree = cKDTree(self.embeddings)
        z = (np.asarray(embedding, dtype=np.float64) - self.center) / self.scale
        k = min(self.k, len(self.embeddings))
        d, _ = self._tree.query(z, k=k)
        return np.asarray(d, dtype=np.float64).reshape(len(z), -1).mean(axis=1)

    def evaluate(self, scores: dict[str, float | None]) -> dict[str, Any]:
        """Flag and the checks that fired for one recording's check scores."""
        fired = [
            name
            for name in CHECKS
            if name in self.thresholds
            and scores.get(name) is not None
            and float(scores[name]) > self.thresholds[name]
        ]
        return {
            "flag": bool(fired),
            "fired": fired,
            "scores": {k: (None if v is None else float(v)) for k, v in scores.items()},
            "thresholds": dict(self.thresholds),
        }


def recording_checks(
    estimate: Any,
    embedding_scores: np.ndarray | None = None,
    feature_score: float | None = None,
    class_edges: list[float] | None = None,
) -> dict[str, float | None]:
    """The check scores of one recording.

    Parameters
    ----------
    estimate : RecordingEstimate
        The aggregated windows (:func:`~stiffnet.uncertainty.aggregate_windows`).
    embedding_scores : numpy.ndarray, optional
        Per-window embedding distances (:meth:`AlarmReference.embedding_scores`).
    feature_score : float, optional
        The inclination-feature OOD score (models without an embedding).
    class_edges : list of float, optional
        Beta edges of the classes, ``[lo, e1, ..., hi]``; the interior ones are used.
    """
    edge = None
    interior = list(class_edges or [])[1:-1]
    if interior and estimate.log_beta is not None and estimate.scale is not None:
        dist = float(np.min(np.abs(estimate.log_beta - np.log(interior))))
        edge = estimate.scale / max(dist, 1e-9)
    return {
        "embedding": None if embedding_scores is None else float(np.median(embedding_scores)),
        "ambiguity": float(1.0 - np.max(estimate.probabilities)),
        "beta_uncertainty": estimate.scale,
        "class_edge": edge,
        "features": feature_score,
    }


def calibrate_thresholds(
    scores: dict[str, np.ndarray], target: float = TARGET_FALSE_ALARM
) -> tuple[dict[str, float], float]:
    """Thresholds at one common percentile of each check, the highest rate <= `target`.

    Parameters
    ----------
    scores : dict
        Check name -> scores of in-distribution units (NaN where a check does
        not apply, e.g. beta uncertainty of a no-contact trajectory).
    target : float
        Largest fraction of the units that may be flagged.

    Returns
    -------
    (dict, float)
        The thresholds and the fraction of the units they flag.
    """
    if not 0.0 < target < 1.0:
        raise ValueError(f"target must be in (0, 1), got {target}")
    names = [n for n, s in scores.items() if np.isfinite(np.asarray(s, float)).any()]
    arrays = {n: np.asarray(scores[n], dtype=np.float64) for n in names}
    if not arrays:
        raise ValueError("no check has scores")

    def thresholds_at(level: float) -> dict[str, float]:
        return {n: float(np.nanquantile(a, level)) for n, a in arrays.items()}

    def rate(th: dict[str, float]) -> float:
        hit = np.zeros(len(next(iter(arrays.values()))), bool)
        for n, a in arrays.items():
            hit |= np.nan_to_num(a, nan=-np.inf) > th[n]
        return float(hit.mean())

    lo, hi = 1.0 - target, 1.0  # rate(hi) == 0; rate(lo) >= target
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if rate(thresholds_at(mid)) <= target:
            hi = mid
        else:
            lo = mid
    th = thresholds_at(hi)
    return th, rate(th)


def save_alarm(path: str | Path, ref: AlarmReference) -> None:
    """Write the reference atomically as ``.npz`` (arrays + JSON metadata)."""
    import io

    from stiffnet.io_utils import write_bytes_atomic

    meta = {
        "format": FORMAT,
        "version": VERSION,
        "thresholds": ref.thresholds,
        "k": ref.k,
        "info": ref.info,
    }
    arrays: dict[str, np.ndarray] = {"meta": np.array(json.dumps(meta))}
    if ref.embeddings is not None:
        arrays.update(
            embeddings=np.asarray(ref.embeddings, np.float32),
            center=np.asarray(ref.center, np.float64),
            scale=np.asarray(ref.scale, np.float64),
        )
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_bytes_atomic(Path(path), buf.getvalue())


def load_alarm(path: str | Path) -> AlarmReference:
    """Read a reference written by :func:`save_alarm`; one-line error when it is not one."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            emb = np.asarray(z["embeddings"], np.float64) if "embeddings" in z else None
            center = np.asarray(z["center"]) if "center" in z else None
            scale = np.asarray(z["scale"]) if "scale" in z else None
    except (OSError, ValueError, KeyError) as exc:
        raise StiffnetError(f"{path}: not a readable alarm reference ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise StiffnetError(f"{path}: not a stiffnet alarm reference")
    th = meta.get("thresholds")
    if not isinstance(th, dict) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in th.values()
    ):
        raise StiffnetError(f"{path}: alarm thresholds must be numbers")
    if "embedding" in th and emb is None:
        raise StiffnetError(f"{path}: the embedding check needs training embeddings")
    return AlarmReference(
        thresholds={str(k): float(v) for k, v in th.items()},
        embeddings=emb,
        center=center,
        scale=scale,
        k=int(meta.get("k", K_NEIGHBOURS)),
        info=dict(meta.get("info") or {}),
    )


def fit_embedding_reference(
    embeddings: np.ndarray, max_rows: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Standardisation and a subsample (at most `max_rows`) of training embeddings."""
    e = np.asarray(embeddings, dtype=np.float64)
    center = e.mean(axis=0)
    scale = e.std(axis=0)
    scale = np.where(scale > 1e-6 * max(1.0, float(scale.max(initial=0.0))), scale, 1.0)
    idx = rng.choice(len(e), size=min(max_rows, len(e)), replace=False) if len(e) else []
    return (e[np.sort(idx)] - center) / scale, center, scale
