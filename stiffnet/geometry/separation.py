"""Separation of contact and free-flight points by tangent magnitude (paper section 5.1, Fig. 8).

During contact the mass decelerates violently, so the reconstructed trajectory
moves much faster there: the histogram of tangent-vector magnitudes has a large
low-magnitude mode (free flight, the "linear plane") and a smaller
high-magnitude mode (contact, the "nonlinear plane"). The paper places the cut
"visually ... where the two distributions overlap". Here it is automatic:

* the cut is **Otsu's threshold on log10 magnitudes** (:func:`otsu_threshold`):
  the cut that maximises the between-class variance of the histogram, i.e. the
  best two-class (2-means) split of the log-magnitudes. Logarithms because the
  contact mode spans one to two decades above the free-flight mode (taller and
  shorter spikes as beta grows); on a log axis both modes have comparable
  widths, Otsu's implicit equal-spread assumption holds, and a gain only shifts
  the histogram, so the cut moves with it (gain invariance). Otsu needs no
  initial guess and no iteration, unlike a two-component Gaussian mixture, and
  unlike "the lowest valley" it does not depend on histogram smoothing.
* a split is always possible, so whether the window has two modes at all is a
  separate **rule** (:func:`separate_contact`): the medians of the two classes
  must be at least ``min_mode_ratio`` (default 2) apart. A window without
  impacts is a smooth closed orbit whose tangent magnitude varies little along
  it (ratio 1.02-1.2 on the simulator's non-impacting responses with 0-9 %
  noise, up to 1.5 at 20 % noise); contact windows give 2.5-50. White noise
  alone gives about 1.9, just below the cut; :func:`stiffnet.geometry.geometric_estimate`
  also requires impacts from :func:`stiffnet.nlts.detect_impacts`, which noise
  alone does not produce.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import ConfigError, SignalError
from stiffnet.nlts._validate import check_int

#: Magnitudes below this fraction of the largest are floored before the log
#: (a zero tangent, e.g. a constant stretch, would give -inf).
_FLOOR = 1e-12


@dataclass(frozen=True)
class ContactSeparation:
    """Result of :func:`separate_contact`.

    Attributes
    ----------
    contact_detected : bool
        True if the magnitude distribution has a distinct high-magnitude mode.
    threshold : float
        Cut-off magnitude (same units as the magnitudes); ``inf`` when no
        contact was detected, so ``magnitudes > threshold`` is all False.
    otsu_threshold : float
        Otsu's cut whether or not it was accepted.
    mask : numpy.ndarray
        Boolean contact mask, ``magnitudes > threshold``.
    counts, edges : numpy.ndarray
        Histogram of ``log10(magnitudes)`` (``edges`` has one more entry).
    separability : float
        Otsu's effectiveness ``eta`` in [0, 1]: between-class over total variance.
    mode_ratio : float
        Ratio of the median magnitudes of the upper and lower classes.
    contact_fraction : float
        Fraction of tangents flagged as contact (0 without contact).
    reason : str
        One line saying why contact was or was not detected.
    """

    contact_detected: bool
    threshold: float
    otsu_threshold: float
    mask: np.ndarray
    counts: np.ndarray
    edges: np.ndarray
    separability: float
    mode_ratio: float
    contact_fraction: float
    reason: str


def log_magnitude_histogram(
    magnitudes: ArrayLike, bins: int = 256
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Histogram of ``log10`` tangent magnitudes (the paper's Fig. 8a, on a log axis).

    Parameters
    ----------
    magnitudes : array_like
        Non-negative tangent magnitudes, e.g. from
        :func:`~stiffnet.geometry.tangent.tangent_magnitudes`.
    bins : int, optional
        Number of equal-width bins between the smallest and largest log-magnitude.

    Returns
    -------
    counts : numpy.ndarray
        Shape ``(bins,)``.
    edges : numpy.ndarray
        Shape ``(bins + 1,)``, in log10 units.
    log_magnitudes : numpy.ndarray
        ``log10`` of the (floored) magnitudes, same shape as the input.
    """
    m = np.asarray(magnitudes, dtype=np.float64)
    if m.ndim != 1 or m.size < 2:
        raise SignalError(f"magnitudes must be 1-D with at least 2 values, got shape {m.shape}")
    if not np.isfinite(m).all() or (m < 0).any():
        raise SignalError("magnitudes must be finite and non-negative")
    top = float(m.max())
    if top == 0:
        raise SignalError("all tangent magnitudes are zero: the trajectory does not move")
    bins = check_int(bins, "bins", 2)
    lm = np.log10(np.maximum(m, _FLOOR * top))
    counts, edges = np.histogram(lm, bins=bins)
    return counts, edges, lm


def otsu_curve(counts: ArrayLike, edges: ArrayLike) -> np.ndarray:
    """Between-class variance of a histogram for every cut (Otsu 1979).

    Parameters
    ----------
    counts : array_like
        Histogram counts, shape (B,).
    edges : array_like
        Bin edges, shape (B + 1,).

    Returns
    -------
    numpy.ndarray
        Shape ``(B - 1,)``: entry k is ``w0 w1 (mu0 - mu1)**2`` (weights as
        fractions) for the cut at ``edges[k + 1]``, class 0 = bins ``0..k``.
    """
    h = np.asarray(counts, dtype=np.float64)
    e = np.asarray(edges, dtype=np.float64)
    if h.ndim != 1 or e.shape != (h.size + 1,) or h.size < 2:
        raise SignalError("counts must be 1-D (>= 2 bins) with edges one longer")
    total = h.sum()
    if total <= 0:
        raise SignalError("histogram is empty")
    c = 0.5 * (e[1:] + e[:-1])
    p = h / total
    w0 = np.cumsum(p)[:-1]
    w1 = 1.0 - w0
    s0 = np.cumsum(p * c)[:-1]
    mu_t = float(np.sum(p * c))
    with np.errstate(invalid="ignore", divide="ignore"):
        mu0 = s0 / w0
        mu1 = (mu_t - s0) / w1
        var_b = w0 * w1 * (mu0 - mu1) ** 2
    return np.where((w0 > 0) & (w1 > 0), var_b, 0.0)


def otsu_threshold(counts: ArrayLike, edges: ArrayLike) -> tuple[float, float]:
    """Rule: Otsu's threshold, the cut maximising the between-class variance.

    Parameters
    ----------
    counts, edges : array_like
        A histogram, e.g. from :func:`log_magnitude_histogram`.

    Returns
    -------
    threshold : float
        The cut, in the units of `edges` (a bin edge; values above it form the
        upper class).
    separability : float
        Otsu's effectiveness ``eta = max var_B / var_T`` in [0, 1]. It is high
        for two well-separated modes but also for a wide flat or arcsine-shaped
        unimodal distribution, so :func:`separate_contact` does not rely on it
        alone.
    """
    var_b = otsu_curve(counts, edges)
    k = int(np.argmax(var_b))
    h = np.asarray(counts, dtype=np.float64)
    e = np.asarray(edges, dtype=np.float64)
    c = 0.5 * (e[1:] + e[:-1])
    p = h / h.sum()
    var_t = float(np.sum(p * (c - np.sum(p * c)) ** 2))
    eta = float(var_b[k] / var_t) if var_t > 0 else 0.0
    return float(e[k + 1]), eta


def separate_contact(
    magnitudes: ArrayLike, bins: int = 256, min_mode_ratio: float = 2.0
) -> ContactSeparation:
    """Split tangents into contact and free flight, or report that there is no contact.

    Otsu's cut on the log10-magnitude histogram (:func:`otsu_threshold`) is
    accepted only if the two classes are distinct modes: the median magnitude
    of the upper class must be at least `min_mode_ratio` times that of the
    lower class (see the module notes for the numbers behind the default).

    Parameters
    ----------
    magnitudes : array_like
        Tangent magnitudes (:func:`~stiffnet.geometry.tangent.tangent_magnitudes`).
    bins : int, optional
        Histogram bins on the log10 axis.
    min_mode_ratio : float, optional
        Smallest accepted ratio of class medians (> 1).

    Returns
    -------
    ContactSeparation
        Threshold, histogram, mask and the criteria.
    """
    if not min_mode_ratio > 1:
        raise ConfigError(f"min_mode_ratio must be > 1, got {min_mode_ratio}")
    counts, edges, lm = log_magnitude_histogram(magnitudes, bins)
    log_cut, eta = otsu_threshold(counts, edges)
    upper = lm > log_cut
    n_up = int(upper.sum())
    if n_up == 0 or n_up == lm.size:
        ratio = 1.0
    else:
        ratio = float(10 ** (np.median(lm[upper]) - np.median(lm[~upper])))
    detected = ratio >= min_mode_ratio
    otsu_cut = float(10**log_cut)
    if detected:
        reason = f"two modes: contact tangents {ratio:.1f}x faster than free flight"
        threshold, mask = otsu_cut, upper
    else:
        reason = (
            f"one mode: Otsu's classes differ by {ratio:.2f}x < {min_mode_ratio:g}x "
            "(no distinct contact mode)"
        )
        threshold, mask = float("inf"), np.zeros(lm.size, dtype=bool)
    return ContactSeparation(
        contact_detected=bool(detected),
        threshold=threshold,
        otsu_threshold=otsu_cut,
        mask=mask,
        counts=counts,
        edges=edges,
        separability=eta,
        mode_ratio=ratio,
        contact_fraction=float(mask.mean()),
        reason=reason,
    )
