"""Reference solution with scipy's ``solve_ivp`` (DOP853) and event location.

An independent implementation of the same piecewise-linear model, used to check
the closed-form engine (``tests/test_simulator_accuracy.py``) and as the speed
baseline (``benchmarks/bench_simulator.py``); a test oracle, so it lives in tests/.
One trajectory at a time, as an efficient user of scipy would write it: scalar
right-hand sides with ``math.sin``, integrate a region until the switching function
``G = min(x - e, F_c)`` changes sign, then restart in the other region.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from stiffnet.simulator.linear import LinearModel


def _scalar_terms(amp: Any, freq: Any, phase: Any) -> list[tuple[float, float, float]]:
    """The non-zero sine terms ``(amplitude, frequency, phase)`` as plain Python floats
    (the right-hand side is called ~10 times per step, where numpy's per-call overhead
    would dominate the cost of a few sines)."""
    return [
        (float(a), float(w), float(p)) for a, w, p in zip(amp, freq, phase, strict=True) if a != 0
    ]


def _regions(model: LinearModel, index: int) -> SimpleNamespace:
    """Trajectory ``index``'s right-hand sides in free flight and in contact, and the
    switching function ``G = min(x - e, F_c)`` as entry and release events."""
    b = model.batch
    beta, xi, e0 = float(b.beta[index]), float(b.damping[index]), float(b.gap[index])
    cc = float(model.contact_damping[index])
    two_xi = 2.0 * xi
    f = model.forcing
    forcing = _scalar_terms(f.amp[index], f.freq[index], f.phase[index])
    gv = model.gap_variation.subset(np.array([index]))
    gap_terms = _scalar_terms(gv.amp[0], gv.freq[0], gv.phase[0])
    sin, cos = math.sin, math.cos

    def force_of(t: float) -> float:
        f = 0.0
        for a, w, p in forcing:
            f += a * sin(w * t + p)
        return f

    def gap(t: float) -> tuple[float, float]:
        e, de = e0, 0.0
        for a, w, p in gap_terms:
            ph = w * t + p
            e += a * sin(ph)
            de += a * w * cos(ph)
        return e, de

    def rhs_free(t, y):
        x, v = y
        return [v, force_of(t) - two_xi * v - x]

    def rhs_contact(t, y):
        x, v = y
        e, de = gap(t)
        fc = beta * (x - e) + cc * (v - de)
        return [v, force_of(t) - two_xi * v - x - fc]

    def entry(t, y):
        x, v = y
        e, de = gap(t)
        d = x - e
        return min(d, beta * d + cc * (v - de))

    def release(t, y):
        return entry(t, y)

    # Directed events: after a restart G is ~0 with either sign, and only a
    # crossing in the direction that leaves the current region counts.
    entry.terminal = release.terminal = True
    entry.direction, release.direction = 1.0, -1.0
    return SimpleNamespace(beta=beta, xi=xi, e0=e0, cc=cc, gv=gv, rhs_free=rhs_free,
                           rhs_contact=rhs_contact, entry=entry, release=release)  # fmt: skip


def _pieces(r: SimpleNamespace, x0: float, v0: float, t_end: float, **solver: Any) -> list:
    """Integrate region by region until ``t_end``: ``(t_start, t_stop, dense solution,
    in contact)`` per piece, each restarted just past the event that ended the last."""
    t, y = 0.0, np.array([x0, v0], dtype=float)
    contact = r.entry(t, y) > 0
    pieces = []
    while t < t_end:
        res = solve_ivp(
            r.rhs_contact if contact else r.rhs_free,
            (t, t_end),
            y,
            method="DOP853",
            events=r.release if contact else r.entry,
            dense_output=True,
            **solver,
        )
        pieces.append((t, res.t[-1], res.sol, contact))
        if res.status != 1:
            break
        t, y = float(res.t_events[0][0]), res.y_events[0][0]
        contact = not contact
    return pieces


def reference_trajectory(
    model: LinearModel,
    index: int,
    x0: float,
    v0: float,
    t_samples: np.ndarray,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_step: float = np.inf,
) -> dict[str, np.ndarray]:
    """Integrate trajectory ``index`` of ``model`` from t=0 and sample it at ``t_samples``.

    ``solve_ivp`` looks for sign changes of the switching function only at the
    ends of its steps, so a shallow contact that begins and ends inside one
    free-flight step (DOP853 takes steps of ~0.2 model time at ``rtol=1e-10``)
    is missed; ``max_step`` bounds the steps to catch those.

    Returns ``x``, ``v`` and ``accel`` (absolute acceleration of the mass).
    """
    r = _regions(model, index)
    t_end = float(t_samples[-1])
    pieces = _pieces(r, x0, v0, t_end, rtol=rtol, atol=atol, max_step=max_step)
    x = np.empty(t_samples.size)
    v = np.empty(t_samples.size)
    acc = np.empty(t_samples.size)
    for t_a, t_b, sol, in_contact in pieces:
        sel = (t_samples >= t_a) & (t_samples <= t_b)
        if not np.any(sel):
            continue
        ts = t_samples[sel]
        yy = sol(ts)
        x[sel], v[sel] = yy[0], yy[1]
        fc = 0.0
        if in_contact:  # gv broadcasts its single row over the sample times
            fc = r.beta * (yy[0] - r.e0 - r.gv.value(ts)) + r.cc * (yy[1] - r.gv.rate(ts))
        acc[sel] = -(2 * r.xi * yy[1] + yy[0] + fc)
    return {"x": x, "v": v, "accel": acc}
