"""Determinism: the Kaplan-Glass vector-field test (paper section 4.2.2).

Kaplan & Glass (1992): coarse-grain the reconstructed phase space into boxes;
each pass of the trajectory through a box gives a unit vector from where it
enters to where it leaves; a deterministic flow has a unique direction in each
small region, so the passes through a box are parallel and their average has
length near 1, whereas for a random process the average of n random unit
vectors has length of order ``1/sqrt(n)``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import ConfigError, SignalError
from stiffnet.nlts._validate import check_int
from stiffnet.nlts.embedding import delay_embed


class VectorField(NamedTuple):
    """Coarse-grained vector field: one row per box the trajectory passes through."""

    boxes: np.ndarray
    """(K, dim) integer box coordinates, 0..n_boxes-1 along each axis."""
    mean_vectors: np.ndarray
    """(K, dim) average unit vector V_k of the passes through box k."""
    passes: np.ndarray
    """(K,) number of passes n_k through box k."""


def approximate_vector_field(y: ArrayLike, n_boxes: int = 8) -> VectorField:
    """Kaplan-Glass coarse-grained vector field of an embedded trajectory (section 4.2.2).

    Each axis of the embedding is cut into `n_boxes` equal intervals over the
    data range (the same number of boxes per dimension). A pass is a maximal
    run of consecutive points in the same box. The trajectory crosses the box
    boundary between the last point outside and the first point inside, so the
    entry and exit points are taken as the midpoints of those two straddling
    samples, and the pass contributes the unit vector from entry to exit. The
    first and last runs (no observed entry or exit) are dropped.

    Parameters
    ----------
    y : array_like
        Embedded trajectory, shape (N, dim), rows in time order (e.g. from
        :func:`~stiffnet.nlts.embedding.delay_embed`).
    n_boxes : int, optional
        Boxes per dimension; ``n_boxes ** dim`` boxes in all (only occupied ones
        are stored).

    Returns
    -------
    VectorField
        Occupied boxes, their average unit vectors and pass counts.
    """
    pts = np.asarray(y, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[0] < 4:
        raise SignalError(f"trajectory must have shape (N >= 4, dim), got {pts.shape}")
    if not np.isfinite(pts).all():
        raise SignalError("trajectory contains NaN or inf values")
    n_boxes = check_int(n_boxes, "n_boxes", 1)
    dim = pts.shape[1]
    if dim * np.log2(n_boxes) >= 62:
        raise ConfigError(f"n_boxes ** dim = {n_boxes}**{dim} boxes is too many to index")
    lo, span = pts.min(axis=0), np.ptp(pts, axis=0)
    span[span == 0] = 1.0  # a constant coordinate: everything in box 0
    cell = np.minimum(((pts - lo) / span * n_boxes).astype(np.int64), n_boxes - 1)
    code = np.ravel_multi_index(cell.T, (n_boxes,) * dim)

    starts = np.flatnonzero(np.diff(code)) + 1  # first point of every run but the first
    if starts.size < 2:
        raise SignalError("trajectory stays in one box; use more boxes or a longer signal")
    first, last = starts[:-1], starts[1:] - 1  # interior runs: first..last inside a box
    entry = 0.5 * (pts[first - 1] + pts[first])
    exit_ = 0.5 * (pts[last] + pts[last + 1])
    step = exit_ - entry
    norm = np.linalg.norm(step, axis=1)
    keep = norm > 0
    unit = step[keep] / norm[keep, None]
    run_code = code[first[keep]]

    box_codes, inverse, counts = np.unique(run_code, return_inverse=True, return_counts=True)
    sums = np.zeros((box_codes.size, dim))
    np.add.at(sums, inverse, unit)
    boxes = np.stack(np.unravel_index(box_codes, (n_boxes,) * dim), axis=1)
    return VectorField(boxes, sums / counts[:, None], counts)


def determinism_factor(field: VectorField, min_passes: int = 2) -> float:
    """Rule: Kaplan-Glass determinism factor of a coarse-grained vector field.

    For box k with n_k passes and average unit vector V_k, a random process
    gives ``E|V_k|^2 = 1/n_k`` (n independent isotropic unit vectors, in any
    dimension), a deterministic flow ``|V_k| = 1``. Kaplan & Glass (1992)
    compare the resultant with this random-walk expectation; in its squared,
    normalised form each box scores

    ``L_k = (|V_k|^2 - 1/n_k) / (1 - 1/n_k)``,

    which is 1 for parallel passes and 0 on average for random ones. The
    factor is the pass-weighted mean over boxes with ``n_k >= min_passes``:

    ``Lambda = sum_k n_k L_k / sum_k n_k``.

    Parameters
    ----------
    field : VectorField
        Output of :func:`approximate_vector_field`.
    min_passes : int, optional
        Boxes visited fewer times are ignored (one pass is trivially parallel).

    Returns
    -------
    float
        Near 1 for deterministic data (the paper reports 0.91), near 0 for
        noise; slightly negative values are possible for noise.
    """
    min_passes = check_int(min_passes, "min_passes", 2)
    n = field.passes.astype(np.float64)
    use = n >= min_passes
    if not use.any():
        raise SignalError(
            f"no box is visited {min_passes} times or more; use fewer boxes or a longer signal"
        )
    n = n[use]
    v2 = np.sum(field.mean_vectors[use] ** 2, axis=1)
    score = (v2 - 1.0 / n) / (1.0 - 1.0 / n)
    return float(np.sum(n * score) / np.sum(n))


def kaplan_glass(
    x: ArrayLike, dim: int, tau: int, n_boxes: int = 8, min_passes: int = 2
) -> tuple[VectorField, float]:
    """Kaplan-Glass determinism test of a scalar signal (section 4.2.2).

    Embeds `x` (:func:`~stiffnet.nlts.embedding.delay_embed`), builds the
    coarse-grained field (:func:`approximate_vector_field`) and scores it
    (:func:`determinism_factor`).

    Returns
    -------
    field : VectorField
        The approximate vector field.
    factor : float
        The determinism factor (1: deterministic, 0: random).

    Notes
    -----
    Use ``tau >= 2``: with ``tau = 1`` consecutive delay vectors share
    ``dim - 1`` samples, so ``dim - 1`` components of every step are fixed by
    the box position and even white noise scores about 0.5.
    """
    field = approximate_vector_field(delay_embed(x, dim, tau), n_boxes)
    return field, determinism_factor(field, min_passes)
