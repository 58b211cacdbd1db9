"""Event resolution of the numerical engine (:mod:`.numerical`): inside a substep, each
switching function's crossing is bracketed (the contact's ``G``, a grazing contact at the
penetration's interior extremum, the effects' event functions), located by a safeguarded
secant (Illinois) on RK4 partial steps from the substep's start (compiled with its
evaluations on a model with the kernel, :meth:`_Partial.secant`), and the rows are stepped
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
#: The Newton locator aims this fraction of the tolerance past its root estimate, so that
#: its last iterate lands on the far side of the root (the state the switch needs).
_FAR_BIAS = 0.25


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


def _hermite_root(
    g0: np.ndarray, d0: np.ndarray, g1: np.ndarray, d1: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """A first guess of the root on ``[0, hi]`` from the cubic Hermite interpolant of a
    function with values ``g0, g1`` and rates ``d0, d1`` at the ends (no evaluation).

    The root of the cubic (Newton on the cubic, kept inside the unit interval by
    bisection), from the linear interpolant's; the linear one where the cubic has no
    sign change. Per row, in Python floats (a located event holds one or two rows).
    """
    out = np.empty(hi.size)
    for i in range(hi.size):
        out[i] = _hermite_root_one(
            float(g0[i]), float(d0[i]), float(g1[i]), float(d1[i]), float(hi[i])
        )
    return out


def _hermite_root_one(g0: float, d0: float, g1: float, d1: float, hi: float) -> float:
    """:func:`_hermite_root` for one row."""
    lin = g0 / (g0 - g1) if g0 != g1 else 0.5
    if not (0.0 < lin < 1.0) or not (math.isfinite(d0) and math.isfinite(d1)):
        return 0.5 * hi if not (0.0 < lin < 1.0) else lin * hi
    m0, m1 = d0 * hi, d1 * hi  # rates per unit of the normalised time
    # p(u) = g0 + m0 u + c2 u^2 + c3 u^3 on [0, 1]
    c2 = 3.0 * (g1 - g0) - 2.0 * m0 - m1
    c3 = 2.0 * (g0 - g1) + m0 + m1
    lo_u, hi_u, u = 0.0, 1.0, lin
    positive_lo = g0 > 0
    for _ in range(8):
        p = g0 + u * (m0 + u * (c2 + u * c3))
        if (p > 0) == positive_lo:
            lo_u = u
        else:
            hi_u = u
        dp = m0 + u * (2.0 * c2 + 3.0 * u * c3)
        nxt = u - p / dp if dp != 0 else math.nan
        if not (lo_u < nxt < hi_u):
            nxt = 0.5 * (lo_u + hi_u)
        if abs(nxt - u) <= 1e-15:
            u = nxt
            break
        u = nxt
    return u * hi if 0.0 < u < 1.0 else lin * hi


def _newton(
    fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    hi: np.ndarray,
    glo: np.ndarray,
    ghi: np.ndarray,
    tol: np.ndarray,
    guess: np.ndarray,
) -> np.ndarray:
    """A root of ``g`` on ``[0, hi]``, where ``fun(s)`` returns ``g(s)`` and an estimate of
    its rate (the penetration and the penetration rate of an RK4 partial step's state).

    The same contract as :func:`_illinois` (``glo = g(0)`` and ``ghi = g(hi)`` differ in
    sign; returns the end of the final bracket on the far side of the root, within ``tol``
    of it) with fewer evaluations: it starts at ``guess`` (the cubic Hermite interpolant's
    root, :func:`_hermite_root`, whose error is of the substep's fourth order) and takes
    Newton steps aimed :data:`_FAR_BIAS` of the tolerance past the root, so an iterate that
    lands on the far side within half the tolerance of the estimated root ends the search.
    The rate read off the state differs from the partial step's exact derivative by the
    step's truncation error, so each step gains about four orders of magnitude: two or
    three evaluations an event where the secant took four to six. Safeguards as the
    secant's: the bracket is kept, and a step that leaves it, or is not at most half the
    step before it (no convergence), bisects.
    """
    if hi.size == 1:
        return np.array(
            [_newton_one(fun, float(hi[0]), float(glo[0]), float(ghi[0]), float(tol[0]),
                         float(guess[0]))]
        )  # fmt: skip
    lo = np.zeros_like(hi)
    sgn = np.sign(glo)
    done = (hi - lo <= tol) | (ghi == 0)
    s = np.where((guess > lo) & (guess < hi), guess, 0.5 * (lo + hi))
    last = np.full(hi.shape, np.inf)  # the previous Newton step's length
    for _ in range(_ROOT_ITERS):
        if done.all():
            break
        s = np.where(done, hi, s)
        g, d = fun(s)
        live = ~done
        near = live & (g * sgn > 0)
        far = live & ~near
        lo, glo = np.where(near, s, lo), np.where(near, g, glo)
        hi, ghi = np.where(far, s, hi), np.where(far, g, ghi)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = -g / d
        close = np.abs(step) <= 0.5 * tol
        done |= live & ((hi - lo <= tol) | (far & close) | (ghi == 0))
        nxt = s + step + _FAR_BIAS * tol
        bad = ~np.isfinite(nxt) | (nxt <= lo) | (nxt >= hi) | ~(np.abs(step) <= 0.5 * last)
        s = np.where(bad, 0.5 * (lo + hi), nxt)
        last = np.where(bad, np.inf, np.abs(step))
    return hi


def _newton_one(
    fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    hi: float,
    glo: float,
    ghi: float,
    tol: float,
    guess: float,
) -> float:
    """:func:`_newton` for one row, in Python floats (the same steps)."""
    lo = 0.0
    positive_lo = glo > 0
    if hi - lo <= tol or ghi == 0:
        return hi
    s = guess if lo < guess < hi else 0.5 * (lo + hi)
    last = math.inf
    for _ in range(_ROOT_ITERS):
        gs, ds = fun(np.array([s]))
        g, d = float(gs[0]), float(ds[0])
        if (g > 0) == positive_lo and g != 0:
            lo = s
        else:
            hi, ghi = s, g
        step = -g / d if d != 0 else math.nan
        if hi - lo <= tol or ghi == 0 or (hi == s and abs(step) <= 0.5 * tol):
            return hi
        nxt = s + step + _FAR_BIAS * tol
        if not (math.isfinite(nxt) and lo < nxt < hi and abs(step) <= 0.5 * last):
            s, last = 0.5 * (lo + hi), math.inf
        else:
            s, last = nxt, abs(step)
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
        # one row (most events): the states by their step length, a dict lookup where the
        # list's search costs numpy calls per state already computed (the secant's
        # evaluations grow it by one each)
        self.one: dict[float, np.ndarray] | None = {} if rows.size == 1 else None

    def state(self, s: np.ndarray) -> np.ndarray:
        """The state after a partial step of length ``s`` (per row)."""
        y = _rk4(self.m, self.t, self.y, self.f, s, self.c, self.mo)
        if self.one is not None:
            self.one[float(s[0])] = y
        self.seen.append((s, y))
        return y

    def aux(self, s: np.ndarray) -> dict[str, np.ndarray]:
        """The right-hand side's ``aux`` after a partial step of length ``s`` (from a state
        already computed at that length where there is one)."""
        seen = self.seen or self.one
        found, y = self.state_at(s) if seen else (np.zeros(s.size, dtype=bool), None)
        if not found.all():
            y = self.state(s)
        return self.m.rhs(self.t + s, y, self.c, self.mo, full=True)[1]

    def value(self, key: str) -> Callable[[np.ndarray], np.ndarray]:
        """``s -> aux[key]``: read off the state where :meth:`_Model.reads_state` allows
        (one right-hand side fewer per evaluation of the root finder)."""
        if self.m.reads_state(key):
            return lambda s: self.m.state_value(self.t + s, self.state(s), key)
        return lambda s: self.aux(s)[key]

    def secant(
        self, root: str | int, hi: np.ndarray, glo: np.ndarray, ghi: np.ndarray, tol: np.ndarray
    ) -> np.ndarray:
        """:func:`_illinois` on ``aux[root]`` (a key, read as :meth:`value` reads it) or on the
        event function ``root`` (an index into ``aux["g"]``).

        On a model with the compiled kernel the secant runs with its partial steps and
        root-function evaluations in one compiled call (:meth:`_Model.kernel_secant`: the
        same IEEE operations in the same order, row by row, so the same roots and states);
        the states it computed are kept as :meth:`state` keeps them. Other models call the
        root function from Python.
        """
        if self.m.kernel is None:
            if isinstance(root, str):
                return _illinois(self.value(root), hi, glo, ghi, tol)
            return _illinois(lambda s: self.aux(s)["g"][:, root], hi, glo, ghi, tol)
        start = (self.t, self.y, self.f, self.c, self.mo)
        at, s_seen, y_seen = self.m.kernel_secant(
            start, root, (hi, glo, ghi, tol), _ROOT_ITERS, _TINY
        )
        if self.one is not None:
            for s, y in zip(s_seen[:, 0].tolist(), y_seen, strict=True):
                self.one[s] = y
        else:
            self.seen.extend(zip(s_seen, y_seen, strict=True))
        return at

    def penetration_and_rate(self) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """``s -> (aux["Gr"], aux["dd"])``, for rows whose contact root function is the
        penetration (:meth:`_Model.root_on_penetration`): the root and its rate from one
        partial step (read off the state where :meth:`_Model.reads_state` allows)."""
        if self.m.reads_state("Gr"):

            def from_state(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                t, y = self.t + s, self.state(s)
                return self.m.state_value(t, y, "Gr"), self.m.state_value(t, y, "dd")

            return from_state

        def from_aux(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            aux = self.aux(s)
            return aux["Gr"], aux["dd"]

        return from_aux

    def event_and_rate(self, j: int) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """``s -> (aux["g"][:, j], its rate)`` (:meth:`_Model.event_rates`), for rows whose
        event function ``j`` has a known rate: both from one partial step and one right-hand
        side, as the secant's evaluation of ``aux["g"]`` costs."""

        def fun(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            t, y = self.t + s, self.state(s)
            dy, aux = self.m.rhs(t, y, self.c, self.mo, full=True)
            return aux["g"][:, j], self.m.event_rates(t, y, dy, aux, self.mo)[:, j]

        return fun

    def state_at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(found (R,), states (R, n_y)): the states already computed at exactly ``s`` (the
        latest where one was computed twice)."""
        if self.one is not None:
            y = self.one.get(float(s[0]))
            if y is None:
                return np.zeros(1, dtype=bool), np.empty_like(self.y)
            return np.ones(1, dtype=bool), y.copy()
        found = np.zeros(s.size, dtype=bool)
        out = np.empty_like(self.y)
        for s_k, y_k in reversed(self.seen):
            hit = ~found & (s_k == s)
            out[hit], found[hit] = y_k[hit], True
            if found.all():
                break
        return found, out


def _brackets(
    st: dict[str, Any],
    ma: _Model,
    a: np.ndarray,
    y1: np.ndarray,
    f1: np.ndarray,
    aux1: dict,
    hs: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Brackets ``[0, s_hi]`` of each switching function's crossing in the rest of the
    substep, and the function's value at ``s_hi``: (A, 1 + n_events) each, NaN where none;
    and each function's rate at ``s_hi`` (A, 1 + n_events), for its first guess: the
    penetration rate at the contact's, the event functions' where their effects give one
    (:meth:`_Model.event_rates`), NaN elsewhere. ``y1, f1, aux1``: the state, right-hand
    side and ``aux`` at the end of the substep.

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
    rate_hi = np.where(out_c, aux1["dd"], np.nan)
    dd0, dd1 = st["aux"]["dd"][a], aux1["dd"]
    turning = ~out_c & np.where(ca, (dd0 < 0) & (dd1 >= 0), (dd0 > 0) & (dd1 <= 0))
    if turning.any():
        sel = turning.nonzero()[0]
        part = _Partial(st, ma, a, sel)
        s_ext = part.secant("dd", la[sel], dd0[sel], dd1[sel], _EXTREMUM_TOL * hs[a[sel]])
        a_ext = part.aux(s_ext)
        hit = a_ext["G"] * sign_in[sel] <= 0
        s_hi[sel[hit], 0], g_hi[sel[hit], 0] = s_ext[hit], a_ext["Gr"][hit]
        rate_hi[sel[hit]] = a_ext["dd"][hit]
    rates = np.full((a.size, 1 + n_ev), np.nan)
    rates[:, 0] = rate_hi
    for j in range(n_ev):
        out_j = aux1["g"][:, j] <= 0
        s_hi[out_j, 1 + j], g_hi[out_j, 1 + j] = la[out_j], aux1["g"][out_j, j]
    if ma.rated_fx and np.isfinite(s_hi[:, 1:]).any():
        rates[:, 1:] = ma.event_rates(st["t"][a] + la, y1, f1, aux1, st["modes"][:, a])
    return s_hi, g_hi, rates


def _first_roots(
    st: dict[str, Any],
    ma: _Model,
    a: np.ndarray,
    s_hi: np.ndarray,
    g_hi: np.ndarray,
    hs: np.ndarray,
    rate_hi: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each bracketed function's first crossing, (A, 1 + n_events), inf where none; and per
    row whether the root finders already computed the state at the earliest crossing (A,),
    and that state (A, n_y).

    Where ``rate_hi`` (each function's rate at ``s_hi``, :func:`_brackets`) is given, a
    crossing whose rate is known at both ends is located by :func:`_newton` from the
    Hermite interpolant's root: the contact's where its root function is the penetration
    (:meth:`_Model.root_on_penetration`), an event function's where its effect gives the
    rate (:meth:`_Model.event_rates`); the others by :func:`_illinois`.
    """
    a0 = {k: v[a] for k, v in st["aux"].items()}
    sign_in = np.where(st["contact"][a], 1.0, -1.0)
    s_root = np.full(s_hi.shape, np.inf)
    finders: list[tuple[np.ndarray, _Partial]] = []
    rate0 = None
    if rate_hi is not None and ma.rated_fx and np.isfinite(s_hi[:, 1:]).any():
        rate0 = ma.event_rates(st["t"][a], st["y"][a], st["f"][a], a0, st["modes"][:, a])
    for col in range(s_hi.shape[1]):
        sel = np.isfinite(s_hi[:, col]).nonzero()[0]
        if sel.size == 0:
            continue
        if col == 0:
            # right after an event G(0) is ~0 with either sign: use the region's
            glo_all = sign_in * np.maximum(np.abs(a0["Gr"]), _TINY)
            newton = None
            if rate_hi is not None:
                newton = ma.root_on_penetration()[sel]
                d0_all = a0["dd"]
        else:
            glo_all = np.maximum(np.abs(a0["g"][:, col - 1]), _TINY)
            newton = None
            if rate0 is not None:
                newton = np.isfinite(rate0[sel, col - 1]) & np.isfinite(rate_hi[sel, col])
                d0_all = rate0[:, col - 1]
        if newton is not None and newton.any():
            sel, rest = sel[newton], sel[~newton]
            part = _Partial(st, ma, a, sel)
            glo, s_top, g_top = glo_all[sel], s_hi[sel, col], g_hi[sel, col]
            guess = _hermite_root(glo, d0_all[sel], g_top, rate_hi[sel, col], s_top)
            fun_r = part.penetration_and_rate() if col == 0 else part.event_and_rate(col - 1)
            s_root[sel, col] = _newton(fun_r, s_top, glo, g_top, _ROOT_TOL * hs[a[sel]], guess)
            finders.append((sel, part))
            sel = rest
            if sel.size == 0:
                continue
        part = _Partial(st, ma, a, sel)
        s_root[sel, col] = part.secant(
            "Gr" if col == 0 else col - 1,
            s_hi[sel, col], glo_all[sel], g_hi[sel, col], _ROOT_TOL * hs[a[sel]],
        )  # fmt: skip
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
