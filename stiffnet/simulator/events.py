"""Event resolution of the numerical engine (:mod:`.numerical`): inside a substep, each
switching function's crossing is bracketed (the contact's ``G``, a grazing contact at the
penetration's interior extremum, the effects' event functions), located by a safeguarded
secant (Illinois) on RK4 partial steps from the substep's start, and the rows are stepped
to their earliest event and switched there (the region, then the effects' modes).

The module notes of :mod:`.numerical` give the switching functions and conventions.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from stiffnet.simulator.rk4 import _rk4

if TYPE_CHECKING:
    from stiffnet.simulator.numerical import _Model

_ROOT_ITERS = 80
_ROOT_TOL = 1e-13  # event-time tolerance, relative to the substep
_EXTREMUM_TOL = 1e-9  # tolerance of the grazing extremum's time, relative to the substep
_TINY = 1e-300


def _illinois(
    fun: Callable[[np.ndarray], np.ndarray],
    hi: np.ndarray,
    glo: np.ndarray,
    ghi: np.ndarray,
    tol: np.ndarray,
) -> np.ndarray:
    """A root of ``fun`` on ``[0, hi]``; ``glo = fun(0)`` and ``ghi = fun(hi)`` differ in sign.

    Safeguarded secant (Illinois variant: the retained end's value is halved
    when it is retained twice, so both ends converge), bisection when the
    secant leaves the bracket. Returns the end of the final bracket on the far
    side of the root (where ``fun`` has left the sign of ``glo``).
    """
    if hi.size == 1:  # most events: one row, where numpy's per-call cost dominates
        return np.array([_illinois_one(fun, float(hi[0]), float(glo[0]), float(ghi[0]), tol)])
    lo = np.zeros_like(hi)
    last = np.zeros(hi.shape, dtype=np.int8)  # -1: lo moved last, +1: hi moved last
    sgn = np.sign(glo)
    for _ in range(_ROOT_ITERS):
        live = (hi - lo > tol) & (ghi != 0)
        if not live.any():
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            s = lo - glo * (hi - lo) / (ghi - glo)
        # glo == _TINY: the interval starts on the boundary (just after an event);
        # a secant would land on s ~ 1e-300, where the state has not moved
        bad = ~np.isfinite(s) | (s <= lo) | (s >= hi) | (np.abs(glo) <= _TINY)
        s = np.where(bad, 0.5 * (lo + hi), s)
        s = np.where(live, s, hi)
        g = fun(s)
        inside = live & (g * sgn > 0)
        outside = live & ~inside
        glo = np.where(outside & (last == 1), 0.5 * glo, glo)
        ghi = np.where(inside & (last == -1), 0.5 * ghi, ghi)
        lo, glo = np.where(inside, s, lo), np.where(inside, g, glo)
        hi, ghi = np.where(outside, s, hi), np.where(outside, g, ghi)
        last = np.where(inside, -1, np.where(outside, 1, last)).astype(np.int8)
    return hi


def _illinois_one(
    fun: Callable[[np.ndarray], np.ndarray], hi: float, glo: float, ghi: float, tol: np.ndarray
) -> float:
    """:func:`_illinois` for one row, in Python floats: the same IEEE operations in the same
    order (bitwise the same root), without numpy's overhead on one-element arrays."""
    tol_ = float(tol[0])
    lo, last = 0.0, 0
    sgn = float(np.sign(glo))
    for _ in range(_ROOT_ITERS):
        if not (hi - lo > tol_ and ghi != 0):
            break
        den = ghi - glo
        s = lo - glo * (hi - lo) / den if den != 0 else math.nan
        if not math.isfinite(s) or s <= lo or s >= hi or abs(glo) <= _TINY:
            s = 0.5 * (lo + hi)
        g = float(fun(np.array([s]))[0])
        if g * sgn > 0:
            if last == -1:
                ghi = 0.5 * ghi
            lo, glo, last = s, g, -1
        else:
            if last == 1:
                glo = 0.5 * glo
            hi, ghi, last = s, g, 1
    return hi


def _finish(
    st: dict[str, Any], a: np.ndarray, sel: np.ndarray, y1: np.ndarray, f1: np.ndarray, aux1: dict
) -> None:
    """Rows ``a[sel]`` end their substep at the trial step (no event left in it)."""
    if not sel.any():
        return
    q = a[sel]
    st["t"][q] = st["t"][q] + st["left"][q]
    st["y"][q], st["f"][q], st["left"][q] = y1[sel], f1[sel], 0.0
    for key in st["aux"]:
        st["aux"][key][q] = aux1[key][sel]


class _Partial:
    """RK4 partial steps of rows ``a[sel]`` from their current state, for the root finders;
    it keeps the states it computed, so the step to the located event reuses its own
    (:meth:`state_at`) instead of recomputing it (bitwise the same numbers)."""

    def __init__(self, st: dict[str, Any], ma: _Model, a: np.ndarray, sel: np.ndarray) -> None:
        rows = a[sel]
        self.m = ma if sel.size == a.size else ma.subset(sel)
        self.t, self.y, self.f = st["t"][rows], st["y"][rows], st["f"][rows]
        self.c, self.mo = st["contact"][rows], st["modes"][:, rows]
        self.seen: list[tuple[np.ndarray, np.ndarray]] = []

    def state(self, s: np.ndarray) -> np.ndarray:
        """The state after a partial step of length ``s`` (per row)."""
        y = _rk4(self.m, self.t, self.y, self.f, s, self.c, self.mo)
        self.seen.append((s, y))
        return y

    def aux(self, s: np.ndarray) -> dict[str, np.ndarray]:
        """The right-hand side's ``aux`` after a partial step of length ``s`` (from a state
        already computed at that length where there is one)."""
        found, y = self.state_at(s) if self.seen else (np.zeros(s.size, dtype=bool), None)
        if not found.all():
            y = self.state(s)
        return self.m.rhs(self.t + s, y, self.c, self.mo, full=True)[1]

    def value(self, key: str) -> Callable[[np.ndarray], np.ndarray]:
        """``s -> aux[key]``: read off the state where :meth:`_Model.reads_state` allows
        (one right-hand side fewer per evaluation of the root finder)."""
        if self.m.reads_state(key):
            return lambda s: self.m.state_value(self.t + s, self.state(s), key)
        return lambda s: self.aux(s)[key]

    def state_at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(found (R,), states (R, n_y)): the states already computed at exactly ``s``."""
        found = np.zeros(s.size, dtype=bool)
        out = np.empty_like(self.y)
        for s_k, y_k in reversed(self.seen):
            hit = ~found & (s_k == s)
            out[hit], found[hit] = y_k[hit], True
            if found.all():
                break
        return found, out


def _brackets(
    st: dict[str, Any], ma: _Model, a: np.ndarray, y1: np.ndarray, aux1: dict, hs: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Brackets ``[0, s_hi]`` of each switching function's crossing in the rest of the
    substep, and the function's value at ``s_hi``: (A, 1 + n_events) each, NaN where none.

    Column 0 is the contact: a sign change of ``G`` over the step, or one hidden between
    two points of the same sign, found at the penetration's interior extremum (grazing);
    the others are the effects' event functions.
    """
    n_ev = len(ma.event_fx)
    la, ca = st["left"][a], st["contact"][a]
    s_hi = np.full((a.size, 1 + n_ev), np.nan)
    g_hi = np.full((a.size, 1 + n_ev), np.nan)
    sign_in = np.where(ca, 1.0, -1.0)
    out_c = aux1["G"] * sign_in <= 0
    s_hi[out_c, 0], g_hi[out_c, 0] = la[out_c], aux1["Gr"][out_c]
    dd0, dd1 = st["aux"]["dd"][a], aux1["dd"]
    turning = ~out_c & np.where(ca, (dd0 < 0) & (dd1 >= 0), (dd0 > 0) & (dd1 <= 0))
    if turning.any():
        sel = turning.nonzero()[0]
        part = _Partial(st, ma, a, sel)
        s_ext = _illinois(
            part.value("dd"), la[sel], dd0[sel], dd1[sel], _EXTREMUM_TOL * hs[a[sel]]
        )  # fmt: skip
        a_ext = part.aux(s_ext)
        hit = a_ext["G"] * sign_in[sel] <= 0
        s_hi[sel[hit], 0], g_hi[sel[hit], 0] = s_ext[hit], a_ext["Gr"][hit]
    for j in range(n_ev):
        out_j = aux1["g"][:, j] <= 0
        s_hi[out_j, 1 + j], g_hi[out_j, 1 + j] = la[out_j], aux1["g"][out_j, j]
    return s_hi, g_hi


def _first_roots(
    st: dict[str, Any],
    ma: _Model,
    a: np.ndarray,
    s_hi: np.ndarray,
    g_hi: np.ndarray,
    hs: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each bracketed function's first crossing (Illinois), (A, 1 + n_events), inf where
    none; and per row whether the root finders already computed the state at the earliest
    crossing (A,), and that state (A, n_y)."""
    a0 = {k: v[a] for k, v in st["aux"].items()}
    sign_in = np.where(st["contact"][a], 1.0, -1.0)
    s_root = np.full(s_hi.shape, np.inf)
    finders: list[tuple[np.ndarray, _Partial]] = []
    for col in range(s_hi.shape[1]):
        sel = np.isfinite(s_hi[:, col]).nonzero()[0]
        if sel.size == 0:
            continue
        part = _Partial(st, ma, a, sel)
        if col == 0:
            # right after an event G(0) is ~0 with either sign: use the region's
            glo = sign_in[sel] * np.maximum(np.abs(a0["Gr"][sel]), _TINY)
            fun = part.value("Gr")
        else:
            glo = np.maximum(np.abs(a0["g"][sel, col - 1]), _TINY)

            def fun(s, _at=part.aux, _j=col - 1):
                return _at(s)["g"][:, _j]

        s_root[sel, col] = _illinois(
            fun, s_hi[sel, col], glo, g_hi[sel, col], _ROOT_TOL * hs[a[sel]]
        )
        finders.append((sel, part))
    s_star = np.min(s_root, axis=1)
    found = np.zeros(a.size, dtype=bool)
    y_star = np.empty((a.size, st["y"].shape[1]))
    for sel, part in finders:
        ok, ys = part.state_at(s_star[sel])
        ok &= ~found[sel]
        y_star[sel[ok]], found[sel[ok]] = ys[ok], True
    return s_root, found, y_star


def _switch(
    st: dict[str, Any],
    ma: _Model,
    a: np.ndarray,
    ev: np.ndarray,
    roots: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> np.ndarray:
    """Step rows ``a[ev]`` to their earliest event and switch there: the restraint region,
    then the effects' modes at the event state. ``roots``: :func:`_first_roots`' output
    for these rows (the event states it computed are reused). Returns the rows moved."""
    s_root, known, y_known = roots
    s_star = np.min(s_root, axis=1)
    fired = s_root <= s_star[:, None] * (1 + 1e-12) + _TINY
    e_rows = a[ev]
    me = ma if ev.size == a.size else ma.subset(ev)
    ce, moe = st["contact"][e_rows].copy(), st["modes"][:, e_rows].copy()
    t0 = st["t"][e_rows]
    te = t0 + s_star
    ye = y_known.copy()
    if not known.all():
        u = (~known).nonzero()[0]
        mu = me if u.size == ev.size else me.subset(u)
        ye[u] = _rk4(mu, t0[u], st["y"][e_rows[u]], st["f"][e_rows[u]], s_star[u], ce[u], moe[:, u])
    flip = fired[:, 0]
    st["entries"][e_rows[flip & ~ce]] += 1
    ce = np.where(flip, ~ce, ce)
    if fired[:, 1:].any():  # the modes' rule reads the forces at the event, before the switch
        _, aux_e = me.rhs(te, ye, st["contact"][e_rows], moe, full=True)
    for j, k in enumerate(me.event_fx):
        fj = fired[:, 1 + j]
        if fj.any():
            new = me.effects[k].next_mode(
                ye[:, 0], ye[:, 1], aux_e["other"][:, k], moe[k], me.params[k]
            )
            moe[k] = np.where(fj, new, moe[k])
    fe, aux_e = me.rhs(te, ye, ce, moe, full=True)
    st["t"][e_rows], st["y"][e_rows], st["f"][e_rows] = te, ye, fe
    st["contact"][e_rows], st["modes"][:, e_rows] = ce, moe
    st["left"][e_rows] = np.maximum(st["left"][e_rows] - s_star, 0.0)
    for key in st["aux"]:
        st["aux"][key][e_rows] = aux_e[key]
    return e_rows
