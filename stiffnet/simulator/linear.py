"""The piecewise-linear impact oscillator and its closed-form pieces.

In each region (free flight, contact) eq. (12) of the paper is a linear ODE with
constant coefficients and a sum of sinusoids (plus a constant) on the right:

    x'' + c x' + k x = C + sum_j [ S_j sin(w_j t) + K_j cos(w_j t) ]

so its solution is a particular part (same sinusoids) plus a homogeneous part
propagated by the 2x2 transition matrix exp(A s), A = [[0, 1], [-k, -c]].

This module holds what every closed-form solver of the model shares: the model
(:class:`LinearModel`), its per-region coefficients (:class:`RegionCoefficients`),
the transition matrix, the coarse-step rule and the event-location budgets. The
production engine is :mod:`stiffnet.simulator.compiled`; the numpy solver in
``tests/reference_closed_form.py`` is its test oracle.
Everything here is vectorised over a leading batch axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stiffnet.effects.base import Sinusoids
from stiffnet.simulator.batch import OscillatorBatch

#: |k - c^2/4| below this is critical damping (neither cos nor cosh).
DISC_TINY = 1e-12
#: Events (entries and releases) located inside one coarse step before the rest of
#: the step is finished in the current region (chatter).
MAX_EVENTS_PER_STEP = 12
#: Safeguarded-Newton iterations per located event (bisection guarantees progress).
NEWTON_ITERATIONS = 60
#: Steps between exact re-evaluations of the forcing phases, which are otherwise
#: carried by rotation; bounds the rotation's round-off.
REANCHOR_EVERY = 512


@dataclass
class LinearModel:
    """The piecewise-linear model of a batch: forcing, gap and contact terms."""

    batch: OscillatorBatch
    forcing: Sinusoids  # F(t), includes a w^2 sin(w t)
    gap_variation: Sinusoids  # e(t) - e
    contact_damping: np.ndarray  # c_c, (B,)


def transition_matrix(k: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Return exp(A s) for x'' + c x' + k x = 0, shape ``(..., 2, 2)``.

    Handles under-, critically and over-damped cases (``k - c**2/4`` of either sign).
    """
    k, c, s = np.broadcast_arrays(np.asarray(k, float), np.asarray(c, float), np.asarray(s, float))
    sig = 0.5 * c
    disc = k - sig * sig
    root = np.sqrt(np.abs(disc))
    under = disc > DISC_TINY
    over = disc < -DISC_TINY
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


class RegionCoefficients:
    """Per-region constants of a :class:`LinearModel`, region 0 free flight, 1 contact.

    ``k``, ``c`` (2, B): stiffness and damping of each region's ODE; ``P``, ``Q``
    (2, B, J) and ``X`` (2, B): its particular solution ``X + sum P sin + Q cos``
    over the frequencies ``freq`` (B, J): the forcing's, then the gap's.
    """

    def __init__(self, model: LinearModel) -> None:
        b = model.batch
        beta, xi, cc = b.beta, b.damping, model.contact_damping
        self.beta, self.cc, self.e0, self.xi = beta, cc, b.gap, xi
        f_amp, f_frq, f_ph = model.forcing.amp, model.forcing.freq, model.forcing.phase
        g_amp, g_frq, g_ph = (
            model.gap_variation.amp,
            model.gap_variation.freq,
            model.gap_variation.phase,
        )
        self.gap_var = model.gap_variation
        self.has_gap_var = g_amp.shape[1] > 0 and np.any(g_amp != 0)
        # One frequency set for both regions: forcing ones then gap ones.
        self.freq = np.concatenate([f_frq, g_frq], axis=1)
        jf = f_frq.shape[1]
        sin_free = np.zeros_like(self.freq)
        cos_free = np.zeros_like(self.freq)
        sin_free[:, :jf] = f_amp * np.cos(f_ph)
        cos_free[:, :jf] = f_amp * np.sin(f_ph)
        # In contact the restraint adds beta*e(t) + c_c*e'(t) on the right-hand side.
        sin_con, cos_con = sin_free.copy(), cos_free.copy()
        gb = beta[:, None] * g_amp
        gc = cc[:, None] * g_amp * g_frq
        sin_con[:, jf:] = gb * np.cos(g_ph) - gc * np.sin(g_ph)
        cos_con[:, jf:] = gb * np.sin(g_ph) + gc * np.cos(g_ph)
        self.k = np.stack([np.ones_like(beta), 1.0 + beta])  # (2, B)
        self.c = np.stack([2 * xi, 2 * xi + cc])
        p0, q0 = particular_coefficients(1.0, 2 * xi[:, None], self.freq, sin_free, cos_free)
        p1, q1 = particular_coefficients(
            (1.0 + beta)[:, None], (2 * xi + cc)[:, None], self.freq, sin_con, cos_con
        )
        self.P = np.stack([p0, p1])  # (2, B, J)
        self.Q = np.stack([q0, q1])
        const_con = np.divide(beta * b.gap, 1.0 + beta)
        self.X = np.stack([np.zeros_like(beta), const_con])  # (2, B)

    def gap(self, idx: np.ndarray, t: np.ndarray):
        """e(t) and e'(t) for trajectories idx."""
        if not self.has_gap_var:
            return self.e0[idx], np.zeros(idx.size)
        sub = self.gap_var.subset(idx)
        return self.e0[idx] + sub.value(t), sub.rate(t)

    def gap_accel(self, idx: np.ndarray, t: np.ndarray) -> np.ndarray:
        if not self.has_gap_var:
            return np.zeros(idx.size)
        sub = self.gap_var.subset(idx)
        ph = sub.freq * t[:, None] + sub.phase
        return -np.sum(sub.amp * sub.freq**2 * np.sin(ph), axis=1)

    def switching_value(self, idx, t, x, v):
        """G = min(x - e, F_c) and the contact force F_c."""
        e, de = self.gap(idx, t)
        d = x - e
        force = self.beta[idx] * d + self.cc[idx] * (v - de)
        return np.minimum(d, force), force


def coarse_steps(model: LinearModel) -> tuple[np.ndarray, np.ndarray]:
    """Free-flight and contact steps per row.

    Short enough that the switching function has at most one extremum per step:
    a fraction of the half period of the fastest free motion (the forcing and its
    harmonics, or the natural frequency) and of the contact's own period.
    """
    b = model.batch
    fastest = np.maximum(1.0, np.max(np.abs(model.forcing.freq), axis=1))
    h_free = np.minimum(0.6, 0.7 / fastest)
    h_contact = np.minimum(h_free, 1.0 / np.sqrt(1.0 + b.beta))
    return h_free, h_contact


def hermite_root(g0: float, r0: float, g1: float, r1: float, length: float) -> float:
    """Start of the root search for an event: the root in (0, length) of the cubic
    Hermite interpolant of G from its values and rates at both ends (G changing sign).

    A few Newton steps on the cubic (bisection-safeguarded), from the secant point;
    the cubic's own error dominates after that. Scalar code: the compiled engine
    jits it, the oracle vectorises it.
    """
    lo, hi = 0.0, 1.0
    a0, b0, a1, b1 = g0, r0 * length, g1, r1 * length
    den = g0 - g1 if g0 != g1 else 1.0
    u = min(max(g0 / den, 0.0), 1.0)
    for _ in range(4):
        u2, u3 = u * u, u * u * u
        p = (2 * u3 - 3 * u2 + 1) * a0 + (u3 - 2 * u2 + u) * b0 + (-2 * u3 + 3 * u2) * a1
        p = p + (u3 - u2) * b1
        dp = (6 * u2 - 6 * u) * (a0 - a1) + (3 * u2 - 4 * u + 1) * b0 + (3 * u2 - 2 * u) * b1
        if (p > 0.0 and g0 > 0.0) or (p < 0.0 and g0 < 0.0) or (p == 0.0 and g0 == 0.0):
            lo = u
        else:
            hi = u
        un = u - p / dp if dp != 0.0 else math.nan
        u = un if math.isfinite(un) and lo < un < hi else 0.5 * (lo + hi)
    return u * length
