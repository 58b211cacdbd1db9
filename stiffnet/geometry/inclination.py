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


@dataclass(frozen=True)
class _OrbitSets:
    """The tangent sets of every complete orbit, flat: ``approach[approach_orbit == k]`` are
    orbit k's approach tangents (ascending), ``hits[hit_orbit == k]`` its impact tangents;
    ``starts``, ``stops``: its impact region."""

    approach: np.ndarray
    approach_orbit: np.ndarray
    hits: np.ndarray
    hit_orbit: np.ndarray
    starts: np.ndarray
    stops: np.ndarray

    @property
    def n_orbits(self) -> int:
        return int(self.starts.size)


def _ranges(first: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``first[k] .. first[k] + count[k] - 1`` for every k, concatenated, and each entry's k."""
    which = np.repeat(np.arange(first.size), count)
    offset = np.cumsum(count) - count
    return first[which] + np.arange(which.size) - offset[which], which


def _orbit_sets(
    contact: np.ndarray, impact: np.ndarray, approach: int, merge_gap: int
) -> _OrbitSets:
    """The approach and impact tangents of each complete orbit, every orbit at once.

    An orbit is an impact region (:func:`impact_regions`) that the window does not cut,
    with at least two impact tangents (a lone one is a noise spike) and an approach: the
    last `approach` free-flight tangents after the previous region and before this one,
    at least :data:`_MIN_POINTS` of them, the last within `approach` tangents of the
    region (the free flight just before it).
    """
    if contact.shape != impact.shape or contact.ndim != 1:
        raise SignalError("contact and impact masks must be 1-D and of the same length")
    approach = check_int(approach, "approach", _MIN_POINTS)
    starts, stops = impact_regions(impact, merge_gap)
    # the free flight searched for an approach begins where the previous region stopped
    lo = np.concatenate(([0], stops[:-1])).astype(np.int64)
    free = np.flatnonzero(~contact)
    n_before, n_lo = np.searchsorted(free, starts), np.searchsorted(free, lo)
    first = np.maximum(n_lo, n_before - approach)
    n_app = n_before - first
    last = free[np.maximum(n_before - 1, 0)] if free.size else np.zeros_like(starts)
    hit_pos = np.flatnonzero(impact)
    h0, h1 = np.searchsorted(hit_pos, starts), np.searchsorted(hit_pos, stops)
    keep = (
        (stops < impact.size)  # a region cut by the end of the window
        & (n_app >= _MIN_POINTS)
        & (starts - last <= approach)
        & (h1 - h0 >= 2)
    )
    app, app_k = _ranges(first[keep], n_app[keep])
    hit, hit_k = _ranges(h0[keep], (h1 - h0)[keep])
    return _OrbitSets(free[app], app_k, hit_pos[hit], hit_k, starts[keep], stops[keep])


def _segment_means(values: np.ndarray, orbit: np.ndarray, n_orbits: int) -> np.ndarray:
    """Mean of ``values`` over each orbit's entries (every orbit has some)."""
    return np.bincount(orbit, values, n_orbits) / np.bincount(orbit, minlength=n_orbits)


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
    k = sets.n_orbits
    return OrbitInclinations(
        before=_segment_means(ang[sets.approach], sets.approach_orbit, k),
        after=_segment_means(ang[sets.hits], sets.hit_orbit, k),
        starts=sets.starts,
        stops=sets.stops,
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
    degree = check_int(degree, "degree", 1)
    k = sets.n_orbits
    return OrbitInclinations(
        before=_curve_inclinations(
            x, z, *_with_lagged(sets.approach, sets.approach_orbit, lag, x.size), k, degree
        ),
        after=_curve_inclinations(
            x, z, *_with_lagged(sets.hits, sets.hit_orbit, lag, x.size), k, degree
        ),
        starts=sets.starts,
        stops=sets.stops,
        method="polynomial",
    )


def _with_lagged(
    idx: np.ndarray, orbit: np.ndarray, lag: int, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each orbit's points: both ends ``i`` and ``i + lag`` of its tangents, once each, in
    order (orbit by orbit, ascending within an orbit)."""
    key = orbit * n + idx  # ascending: orbit by orbit, each orbit's tangents in order
    both = np.concatenate((key, key + lag))
    # two ascending runs: a stable sort merges them in linear time (np.unique's hashing
    # took twenty times longer on a record's few thousand points)
    both.sort(kind="stable")
    first = np.ones(both.size, dtype=bool)
    first[1:] = both[1:] != both[:-1]
    both = both[first]
    return both % n, both // n


def _curve_inclinations(
    x: np.ndarray, z: np.ndarray, pts: np.ndarray, orbit: np.ndarray, n_orbits: int, degree: int
) -> np.ndarray:
    """:func:`curve_inclination` of the points ``pts`` of each orbit, every orbit at once.

    The same rule: each orbit's fit runs along the coordinate that spreads more,
    on the abscissa centred and scaled by its span; the slope at the centroid is
    the fit's linear coefficient (degree 1: the closed-form least-squares slope,
    from per-orbit sums; higher degrees: every orbit's scaled Vandermonde
    system solved as one stack, as :func:`numpy.polynomial.polynomial.polyfit`
    solves one).
    """
    if n_orbits == 0:
        return np.empty(0)
    count = np.bincount(orbit, minlength=n_orbits)
    if count.min() < degree + 2:
        raise SignalError(f"need matching 1-D x and z with >= {degree + 2} points")
    bounds = np.concatenate(([0], np.cumsum(count)[:-1]))
    xs, zs = x[pts], z[pts]
    ptp_x = np.maximum.reduceat(xs, bounds) - np.minimum.reduceat(xs, bounds)
    ptp_z = np.maximum.reduceat(zs, bounds) - np.minimum.reduceat(zs, bounds)
    steep = ptp_z > ptp_x
    u, w = np.where(steep[orbit], zs, xs), np.where(steep[orbit], xs, zs)
    span = np.where(steep, ptp_z, ptp_x)
    flat = span == 0  # every point the same: no direction to read
    safe = np.where(flat, 1.0, span)
    t = (u - (np.bincount(orbit, u, n_orbits) / count)[orbit]) / safe[orbit]
    with np.errstate(divide="ignore", invalid="ignore"):  # the flat orbits are set below
        if degree == 1:
            dw = w - (np.bincount(orbit, w, n_orbits) / count)[orbit]
            g1 = np.bincount(orbit, t * dw, n_orbits) / np.bincount(orbit, t * t, n_orbits)
        else:
            g1 = _linear_coefficients(t, w, orbit, count, bounds, degree)
        g = np.abs(g1) / safe  # d(w)/d(u) at the centroid
        deg = np.degrees(np.where(steep, np.arctan2(1.0, g), np.arctan(g)))
    return np.where(flat, np.where(steep, 90.0, 0.0), deg)


def _linear_coefficients(
    t: np.ndarray,
    w: np.ndarray,
    orbit: np.ndarray,
    count: np.ndarray,
    bounds: np.ndarray,
    degree: int,
) -> np.ndarray:
    """The coefficient of ``t`` in each orbit's least-squares polynomial of `degree`.

    Each orbit's Vandermonde matrix is padded with zero rows to the longest
    orbit's length (a zero row changes no least-squares solution), its columns
    scaled to unit norm and the stack solved by the pseudo-inverse with
    polyfit's cut-off (``len * eps``): polyfit's own steps, on every orbit at once.
    """
    n_orbits, longest = count.size, int(count.max())
    row = np.arange(t.size) - bounds[orbit]
    van = np.zeros((n_orbits, longest, degree + 1))
    van[orbit, row] = t[:, None] ** np.arange(degree + 1)
    rhs = np.zeros((n_orbits, longest))
    rhs[orbit, row] = w
    scale = np.sqrt(np.sum(van * van, axis=1))
    scale[scale == 0] = 1
    coef = np.linalg.pinv(van / scale[:, None, :], rcond=count * np.finfo(float).eps)
    return (coef @ rhs[..., None])[:, 1, 0] / scale[:, 1]


def check_method(method: str) -> str:
    """Return `method` if it is ``"gradient"`` or ``"polynomial"``, else raise ConfigError."""
    if method not in ("gradient", "polynomial"):
        raise ConfigError(f"unknown inclination method {method!r}; expected gradient or polynomial")
    return method
