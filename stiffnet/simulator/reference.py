"""Reference solution with scipy's ``solve_ivp`` (DOP853) and event location.

An independent implementation of the same piecewise-linear model, used to check
the closed-form engine (accuracy test) and as the speed baseline
(``benchmarks/bench_simulator.py``). One trajectory at a time, as a user of
scipy would write it: integrate a region until the switching function
``G = min(x - e, F_c)`` changes sign, then restart in the other region.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from stiffnet.simulator.closed_form import LinearModel


def reference_trajectory(
    model: LinearModel,
    index: int,
    x0: float,
    v0: float,
    t_samples: np.ndarray,
    rtol: float = 1e-10,
    atol: float = 1e-12,
) -> dict[str, np.ndarray]:
    """Integrate trajectory ``index`` of ``model`` from t=0 and sample it at ``t_samples``.

    Returns ``x``, ``v`` and ``accel`` (absolute acceleration of the mass).
    """
    b = model.batch
    beta, xi, e0 = b.beta[index], b.damping[index], b.gap[index]
    cc = model.contact_damping[index]
    f = model.forcing.subset(np.array([index]))
    gv = model.gap_variation.subset(np.array([index]))

    def gap(t):
        tt = np.atleast_1d(t)
        return e0 + gv.value(tt)[0], gv.rate(tt)[0]

    def force(t, y):
        e, de = gap(t)
        return beta * (y[0] - e) + cc * (y[1] - de), y[0] - e

    def rhs_free(t, y):
        return [y[1], f.value(np.atleast_1d(t))[0] - 2 * xi * y[1] - y[0]]

    def rhs_contact(t, y):
        fc, _ = force(t, y)
        return [y[1], f.value(np.atleast_1d(t))[0] - 2 * xi * y[1] - y[0] - fc]

    def entry(t, y):
        fc, d = force(t, y)
        return min(d, fc)

    def release(t, y):
        return entry(t, y)

    # Directed events: after a restart G is ~0 with either sign, and only a
    # crossing in the direction that leaves the current region counts.
    entry.terminal = release.terminal = True
    entry.direction, release.direction = 1.0, -1.0
    t_end = float(t_samples[-1])
    t, y = 0.0, np.array([x0, v0], dtype=float)
    contact = entry(t, y) > 0
    pieces = []
    while t < t_end:
        res = solve_ivp(
            rhs_contact if contact else rhs_free,
            (t, t_end),
            y,
            method="DOP853",
            rtol=rtol,
            atol=atol,
            events=release if contact else entry,
            dense_output=True,
        )
        t_stop = res.t[-1]
        pieces.append((t, t_stop, res.sol, contact))
        if res.status == 1:
            # restart just past the event in the other region
            t, y = float(res.t_events[0][0]), res.y_events[0][0]
            contact = not contact
        else:
            break
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
            fc = beta * (yy[0] - e0 - gv.value(ts)) + cc * (yy[1] - gv.rate(ts))
        acc[sel] = -(2 * xi * yy[1] + yy[0] + fc)
    return {"x": x, "v": v, "accel": acc}
