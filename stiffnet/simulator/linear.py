"""Closed-form pieces of the piecewise-linear oscillator.

In each region (free flight, contact) eq. (12) of the paper is a linear ODE with
constant coefficients and a sum of sinusoids (plus a constant) on the right:

    x'' + c x' + k x = C + sum_j [ S_j sin(w_j t) + K_j cos(w_j t) ]

so its solution is a particular part (same sinusoids) plus a homogeneous part
propagated by the 2x2 transition matrix exp(A s), A = [[0, 1], [-k, -c]].
Everything here is vectorised over a leading batch axis.
"""

from __future__ import annotations

import numpy as np

_TINY = 1e-12


def transition_matrix(k: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Return exp(A s) for x'' + c x' + k x = 0, shape ``(..., 2, 2)``.

    Handles under-, critically and over-damped cases (``k - c**2/4`` of either sign).
    """
    k, c, s = np.broadcast_arrays(np.asarray(k, float), np.asarray(c, float), np.asarray(s, float))
    sig = 0.5 * c
    disc = k - sig * sig
    root = np.sqrt(np.abs(disc))
    under = disc > _TINY
    over = disc < -_TINY
    rs = root * s
    # cos-like and sin/omega-like functions of the homogeneous solution
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        cf = np.where(under, np.cos(rs), np.where(over, np.cosh(rs), 1.0))
        sf = np.where(
            under,
            np.sin(rs) / np.where(under, root, 1.0),
            np.where(over, np.sinh(rs) / np.where(over, root, 1.0), s),
        )
    decay = np.exp(-sig * s)
    out = np.empty(k.shape + (2, 2))
    out[..., 0, 0] = decay * (cf + sig * sf)
    out[..., 0, 1] = decay * sf
    out[..., 1, 0] = -decay * k * sf
    out[..., 1, 1] = decay * (cf - sig * sf)
    return out


def particular_coefficients(
    k: np.ndarray, c: np.ndarray, w: np.ndarray, sin_amp: np.ndarray, cos_amp: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients (P, Q) of x_p = P sin(w t) + Q cos(w t).

    Solves x'' + c x' + k x = S sin(w t) + K cos(w t); all inputs broadcast. With
    damping c > 0 the 2x2 system is never singular, even at resonance.
    """
    kw = k - w * w
    cw = c * w
    det = kw * kw + cw * cw
    det = np.where(det == 0.0, np.inf, det)  # undamped exact resonance: drop the term
    p = (kw * sin_amp + cw * cos_amp) / det
    q = (kw * cos_amp - cw * sin_amp) / det
    return p, q
