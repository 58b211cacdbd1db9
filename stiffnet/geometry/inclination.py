"""Inclination of the free-flight and contact planes in the x-z projection (section 5.1, eqs 7-10).

Coordinates. For a delay embedding ``Y_i = (s_i, s_{i+tau}, s_{i+2 tau}, ...)``
the paper's x is the first delay coordinate ``s_i`` and z the third
``s_{i+2 tau}``; the x-z projection is its "x_t - x_{t+2 tau}" plane (Fig. 2b).

Which points are "after" and "before" the impact. Going forward in time an
impact enters the delay vector through its *latest* sample first: the
trajectory leaves the free-flight ("linear") plane along z, then along y and x
as the spike moves through the earlier coordinates. In the x-z projection the
contact ("nonlinear") plane is therefore the excursion along z, during which x
(the signal ``2 tau`` earlier) barely moves - a nearly vertical branch that
steepens as beta grows (taller, shorter spikes). Here

* the **impact region** of an orbit is a run of tangents whose z-component
  exceeds the contact threshold, ``|V_z| > threshold`` (runs closer than
  `merge_gap` are one impact: ``V_z`` passes through zero at the spike's tip);
* the **approach** ("before the impact") is the last `approach` free-flight
  tangents before that region (``|V| <= threshold``), i.e. the stretch of the
  linear plane from which the trajectory escapes.

The x- and y-excursions of the same spike are contact tangents too (they count
in the contact fraction) but belong to neither set. Angles are inclinations to
the x axis in ``[0, 90]`` degrees, ``atan(|dz| / |dx|)``: they do not depend on
the direction of travel, on the signal's polarity (``(x, z) -> (-x, -z)``) or
on its gain.

Two estimators, as in the paper:

* :func:`gradient_inclinations`: eqs 9-10, ``theta = atan(c / a)`` from the x
  and z components (a, c) of every tangent, averaged over the approach and over
  the impact region of each orbit (Fig. 11);
* :func:`polynomial_inclinations`: a polynomial fitted through the embedded
  points of the approach and of the impact region of each orbit; the gradient
  of each curve at its centroid is the inclination (Table 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import ConfigError, SignalError
from stiffnet.nlts._validate import check_int

#: An orbit needs at least this many tangents in each of its two sets.
_MIN_POINTS = 3


@dataclass(frozen=True)
class OrbitInclinations:
    """Inclinations per orbit (one orbit = one impact and the free flight before it).

    Attributes
    ----------
    before, after : numpy.ndarray
        Degrees in [0, 90], one per orbit: the approach (free-flight plane)
        and the impact region (contact plane).
    starts, stops : numpy.ndarray
        Tangent indices of each orbit's impact region, ``[start, stop)``.
    method : str
        ``"gradient"`` or ``"polynomial"``.
    """

    before: np.ndarray
    after: np.ndarray
    starts: np.ndarray
    stops: np.ndarray
    method: str

    @property
    def n_orbits(self) -> int:
        return int(self.before.size)

    @property
    def mean_before(self) -> float:
        """Average inclination before the impact (NaN without orbits)."""
        return float(np.mean(self.before)) if self.before.size else float("nan")

    @property
    def mean_after(self) -> float:
        """Average inclination after the impact (NaN without orbits)."""
        return float(np.mean(self.after)) if self.after.size else float("nan")


def xz_projection(y: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The x-z projection of an embedding: ``x = Y[:, 0] = s_t``, ``z = Y[:, 2] = s_{t+2 tau}``."""
    pts = np.asarray(y, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] < 3:
        raise SignalError(f"embedding must have shape (N, m >= 3), got {pts.shape}")
    return pts[:, 0], pts[:, 2]


def tangent_inclinations(v: ArrayLike) -> np.ndarray:
    """Inclination of each tangent in the x-z projection, ``atan(|c| / |a|)`` (eqs 9-10).

    Parameters
    ----------
    v : array_like
        Tangent vectors, shape (N, m >= 3): ``a = V[:, 0]``, ``c = V[:, 2]``
        (eqs 7-8).

    Returns
    -------
    numpy.ndarray
        Degrees in [0, 90]; 90 for a purely vertical (z) step, 0 for a
        horizontal one (``arctan2`` keeps ``a = 0`` finite).
    """
    a, c = xz_projection(v)
    return np.degrees(np.arctan2(np.abs(c), np.abs(a)))


def impact_regions(impact: ArrayLike, merge_gap: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Runs of True in a tangent mask, merging runs separated by <= `merge_gap` False entries.

    Parameters
    ----------
    impact : array_like of bool
        E.g. ``|V_z| > threshold``.
    merge_gap : int, optional
        Longest gap bridged (one spike can dip below the threshold at its tip).

    Returns
    -------
    starts, stops : numpy.ndarray
        Int arrays; run k covers indices ``starts[k]..stops[k]-1``.
    """
    m = np.asarray(impact, dtype=bool)
    if m.ndim != 1:
        raise SignalError("impact mask must be 1-D")
    merge_gap = check_int(merge_gap, "merge_gap", 0)
    d = np.diff(np.concatenate(([0], m.astype(np.int8), [0])))
    starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    if starts.size > 1 and merge_gap > 0:
        keep = np.concatenate(([True], starts[1:] - stops[:-1] > merge_gap))
        starts = starts[keep]
        stops = np.concatenate((stops[:-1][keep[1:]], stops[-1:]))
    return starts, stops


def _orbit_sets(
    contact: np.ndarray, impact: np.ndarray, approach: int, merge_gap: int
) -> list[tuple[np.ndarray, np.ndarray, int, int]]:
    """(approach indices, impact indices, start, stop) for each complete orbit."""
    if contact.shape != impact.shape or contact.ndim != 1:
        raise SignalError("contact and impact masks must be 1-D and of the same length")
    approach = check_int(approach, "approach", _MIN_POINTS)
    starts, stops = impact_regions(impact, merge_gap)
    free = ~contact
    out = []
    prev_stop = 0
    for start, stop in zip(starts, stops, strict=True):
        lo = prev_stop
        prev_stop = stop
        if stop >= impact.size:  # region cut by the end of the window
            break
        cand = np.flatnonzero(free[lo:start]) + lo
        app = cand[-approach:]
        # An approach must reach the impact region: the free flight just before it.
        if app.size < _MIN_POINTS or start - app[-1] > approach:
            continue
        hit = np.flatnonzero(impact[start:stop]) + start
        if hit.size < 2:  # a lone tangent is a noise spike, not an impact
            continue
        out.append((app, hit, start, stop))
    return out


def gradient_inclinations(
    v: ArrayLike,
    contact: ArrayLike,
    impact: ArrayLike,
    approach: int,
    merge_gap: int = 0,
) -> OrbitInclinations:
    """Gradient approach (eqs 7-10): mean tangent inclination before and after each impact.

    Parameters
    ----------
    v : array_like
        Tangent vectors, shape (N, m >= 3).
    contact : array_like of bool
        Contact tangents (any coordinate), e.g. ``ContactSeparation.mask``.
    impact : array_like of bool
        Tangents whose z-component is in contact, ``|V_z| > threshold``.
    approach : int
        Free-flight tangents averaged before each impact region.
    merge_gap : int, optional
        See :func:`impact_regions`.

    Returns
    -------
    OrbitInclinations
        ``before[k]``: mean of :func:`tangent_inclinations` over the approach
        of orbit k; ``after[k]``: over its impact region (eqs 9 and 10).
    """
    ang = tangent_inclinations(v)
    c = np.asarray(contact, dtype=bool)
    z = np.asarray(impact, dtype=bool)
    if c.size != ang.size:
        raise SignalError(f"masks have {c.size} entries for {ang.size} tangents")
    sets = _orbit_sets(c, z, approach, merge_gap)
    before = np.array([ang[a].mean() for a, _, _, _ in sets])
    after = np.array([ang[h].mean() for _, h, _, _ in sets])
    return OrbitInclinations(
        before=before,
        after=after,
        starts=np.array([s for _, _, s, _ in sets], dtype=np.int64),
        stops=np.array([e for _, _, _, e in sets], dtype=np.int64),
        method="gradient",
    )


def curve_inclination(x: ArrayLike, z: ArrayLike, degree: int = 1) -> float:
    """Inclination of a polynomial fitted through points of the x-z plane, in degrees.

    The polynomial is fitted along whichever coordinate spreads more (z as a
    function of x for a flat branch, x as a function of z for a steep one), so
    a nearly vertical contact branch is as well conditioned as a flat one; the
    gradient ``dz/dx`` at the centroid gives the inclination ``atan(|dz/dx|)``.

    Parameters
    ----------
    x, z : array_like
        Coordinates of the points, at least ``degree + 2`` of them.
    degree : int, optional
        Polynomial degree (1: a straight line).

    Returns
    -------
    float
        Degrees in [0, 90].
    """
    xx = np.asarray(x, dtype=np.float64)
    zz = np.asarray(z, dtype=np.float64)
    degree = check_int(degree, "degree", 1)
    if xx.shape != zz.shape or xx.ndim != 1 or xx.size < degree + 2:
        raise SignalError(f"need matching 1-D x and z with >= {degree + 2} points")
    steep = np.ptp(zz) > np.ptp(xx)
    u, w = (zz, xx) if steep else (xx, zz)
    span = np.ptp(u)
    if span == 0:
        return 90.0 if steep else 0.0
    # Centre and scale the abscissa: the fit is then well conditioned and the
    # derivative at the centroid is the linear coefficient.
    t = (u - u.mean()) / span
    if degree == 1:  # closed-form least-squares slope (per-orbit fits dominate the run time)
        g1 = float(np.dot(t, w - w.mean()) / np.dot(t, t))
    else:
        g1 = float(np.polynomial.polynomial.polyfit(t, w, degree)[1])
    g = abs(g1) / span  # d(w)/d(u) at the centroid
    return float(np.degrees(np.arctan2(1.0, g) if steep else np.arctan(g)))


def polynomial_inclinations(
    y: ArrayLike,
    contact: ArrayLike,
    impact: ArrayLike,
    approach: int,
    lag: int = 1,
    merge_gap: int = 0,
    degree: int = 1,
) -> OrbitInclinations:
    """Polynomial-fit approach (Table 1): gradients of curves fitted before and after each impact.

    Parameters
    ----------
    y : array_like
        Embedded trajectory, shape (N, m >= 3).
    contact, impact : array_like of bool
        Tangent masks as in :func:`gradient_inclinations` (length ``N - lag``).
    approach : int
        Free-flight tangents before each impact region.
    lag : int, optional
        Tangent lag the masks were computed with: tangent i joins points i and
        ``i + lag``, and both ends are used in the fit.
    merge_gap : int, optional
        See :func:`impact_regions`.
    degree : int, optional
        Polynomial degree (see :func:`curve_inclination`).

    Returns
    -------
    OrbitInclinations
        One fit per set and orbit.
    """
    x, z = xz_projection(y)
    c = np.asarray(contact, dtype=bool)
    h = np.asarray(impact, dtype=bool)
    lag = check_int(lag, "lag", 1)
    if c.size != x.size - lag:
        raise SignalError(f"masks have {c.size} entries for {x.size - lag} tangents")
    sets = _orbit_sets(c, h, approach, merge_gap)

    def fit(idx: np.ndarray) -> float:
        pts = np.union1d(idx, idx + lag)
        return curve_inclination(x[pts], z[pts], degree)

    return OrbitInclinations(
        before=np.array([fit(a) for a, _, _, _ in sets]),
        after=np.array([fit(i) for _, i, _, _ in sets]),
        starts=np.array([s for _, _, s, _ in sets], dtype=np.int64),
        stops=np.array([e for _, _, _, e in sets], dtype=np.int64),
        method="polynomial",
    )


def check_method(method: str) -> str:
    """Return `method` if it is ``"gradient"`` or ``"polynomial"``, else raise ConfigError."""
    if method not in ("gradient", "polynomial"):
        raise ConfigError(f"unknown inclination method {method!r}; expected gradient or polynomial")
    return method
