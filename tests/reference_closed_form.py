"""Test oracle: the closed-form solver of the piecewise-linear oscillator in numpy.

Not used by :class:`~stiffnet.simulator.simulator.Simulator` (its engine is
:mod:`stiffnet.simulator.compiled`); the accuracy tests run the compiled engine
against this and against scipy's ``solve_ivp`` (``tests/reference_solve_ivp.py``).
It shares the model and the coarse-step rule (:mod:`stiffnet.simulator.linear`)
but not the execution: numpy calls over the whole batch, events logged while
marching and every sample evaluated afterwards from its segment's closed form,
and its own safeguarded Newton over the batch.

Within a region (free flight or contact) eq. (12) is linear with sinusoidal
forcing, so one sampling step is exact: subtract the particular solution,
multiply by the transition matrix, add the particular solution back. Contact
onset and release are located by safeguarded Newton iteration on the
closed-form solution (not snapped to the sampling grid), including contacts
that begin and end inside one step (grazing), found from the interior
extremum of the switching function.

The switching function is ``G = min(x - e(t), F_c)`` with the contact force
``F_c = beta (x - e) + c_c (v - e')``: the mass is in contact exactly when
``G > 0``; with contact damping the restraint releases when the force would
turn to a pull, before the penetration is zero ("the restraint never pulls").
"""

from __future__ import annotations

import numpy as np

from stiffnet.simulator.linear import (
    DISC_TINY,
    MAX_EVENTS_PER_STEP,
    NEWTON_ITERATIONS,
    REANCHOR_EVERY,
    LinearModel,
    RegionCoefficients,
    coarse_steps,
    hermite_root,
    transition_matrix,
)
from stiffnet.simulator.result import EngineResult


class _Segment:
    """Closed-form solution from a state, staying in one region, for many rows.

    Precomputes everything that does not depend on the elapsed time ``s`` so the
    Newton iterations of event location cost one trig evaluation each.
    """

    def __init__(self, reg: RegionCoefficients, idx, region, t0, x0, v0) -> None:
        self.reg, self.idx, self.region, self.t0 = reg, idx, region, t0
        self.f, self.P, self.Q, self.X = (
            reg.freq[idx],
            reg.P[region, idx],
            reg.Q[region, idx],
            reg.X[region, idx],
        )
        xp0, vp0, _ = self._particular(t0)
        self.z0, self.z1 = x0 - xp0, v0 - vp0
        self.k, self.c = reg.k[region, idx], reg.c[region, idx]
        self.sig = 0.5 * self.c
        disc = self.k - self.sig**2
        self.root = np.sqrt(np.abs(disc))
        self.all_under = bool(np.all(disc > DISC_TINY))
        self.disc = disc

    def subset(self, rows: np.ndarray) -> _Segment:
        """The same segment restricted to ``rows`` (no recomputation)."""
        new = object.__new__(_Segment)
        new.reg, new.all_under = self.reg, self.all_under
        for name in ("idx", "region", "t0", "f", "P", "Q", "X", "z0", "z1", "k", "c", "sig",
                     "root", "disc"):  # fmt: skip
            setattr(new, name, getattr(self, name)[rows])
        return new

    def _cf_sf(self, s):
        rs = self.root * s
        if self.all_under:
            return np.cos(rs), np.sin(rs) / self.root
        m = transition_matrix(self.k, self.c, s)  # rare over/critical damping
        decay = np.exp(-self.sig * s)
        sf = m[:, 0, 1] / decay
        return m[:, 0, 0] / decay - self.sig * sf, sf

    def state(self, s):
        """x, v and acceleration (of the region's ODE) at t0 + s."""
        cf, sf = self._cf_sf(s)
        decay = np.exp(-self.sig * s)
        z0, z1, sig = self.z0, self.z1, self.sig
        xh = decay * ((cf + sig * sf) * z0 + sf * z1)
        vh = decay * (-self.k * sf * z0 + (cf - sig * sf) * z1)
        xp, vp, ap = self._particular(self.t0 + s)
        return xh + xp, vh + vp, ap - self.k * xh - self.c * vh

    def _particular(self, t):
        ph = self.f * t[:, None]
        return _particular_sum(self.X, self.P, self.Q, self.f, np.sin(ph), np.cos(ph))

    def switching(self, s):
        """G = min(x - e, F_c) and its rate at t0 + s."""
        reg, idx = self.reg, self.idx
        x, v, a = self.state(s)
        t = self.t0 + s
        e, de = reg.gap(idx, t)
        d, dd = x - e, v - de
        beta, cc = reg.beta[idx], reg.cc[idx]
        force = beta * d + cc * dd
        rate = np.where(d <= force, dd, beta * dd + cc * (a - reg.gap_accel(idx, t)))
        return np.minimum(d, force), rate


def _particular_sum(X, P, Q, f, sn, cs):
    """x_p, v_p, a_p from the coefficients and sin/cos of the phases."""
    ps = P * sn + Q * cs
    xp = X + ps.sum(axis=1)
    vp = (f * (P * cs - Q * sn)).sum(axis=1)
    ap = -(f * f * ps).sum(axis=1)
    return xp, vp, ap


_hermite_starts = np.vectorize(hermite_root, otypes=[float])


def _locate_root(seg, lo, hi, glo, ghi, tol, fun=None, start=None):
    """Safeguarded Newton: a root of G on [lo, hi] where glo and ghi differ in sign.

    ``seg`` gives ``switching(s) -> (G, G')`` (or ``fun(seg, s)`` does) and
    ``subset(rows)``; rows that have converged drop out of the iteration.
    ``start`` is an optional first guess inside the bracket.
    """
    fun = fun or (lambda sg, x: sg.switching(x))
    s = np.clip(lo - glo * (hi - lo) / np.where(ghi != glo, ghi - glo, 1.0), lo, hi)
    if start is not None:
        s = np.clip(start, lo, hi)
    # Starting on the boundary (right after an event, G(lo) ~ 0) the secant guess is
    # lo itself, where G may be exactly 0: bisect first so that point is not taken
    # for the root and the region does not flip back and forth.
    on_boundary = np.abs(glo) <= 1e-12 * np.maximum(np.abs(ghi), 1e-300)
    s = np.where(on_boundary, 0.5 * (lo + hi), s)
    out = s.copy()
    rows = np.arange(s.size)
    for _ in range(NEWTON_ITERATIONS):
        g, dg = fun(seg, s)
        left = np.sign(g) == np.sign(glo)
        lo, glo = np.where(left, s, lo), np.where(left, g, glo)
        hi, ghi = np.where(left, hi, s), np.where(left, ghi, g)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = g / dg
        sn = s - step
        bad = ~np.isfinite(sn) | (sn <= lo) | (sn >= hi)
        # Converged: an exact root, or a Newton step below round-off (it may fall
        # just outside the bracket, which must not send the row back to bisection).
        fine = (g == 0) | (np.abs(step) <= tol)
        s_new = np.where(fine, s, np.where(bad, 0.5 * (lo + hi), sn))
        done = fine | (np.abs(s_new - s) <= tol) | (hi - lo <= tol)
        out[rows] = s_new
        if np.all(done):
            break
        keep = ~done
        if np.count_nonzero(keep) <= 0.5 * keep.size:
            seg = seg.subset(keep)
            rows, s_new, lo, hi, glo, ghi, tol = (
                a[keep] for a in (rows, s_new, lo, hi, glo, ghi, tol)
            )
        s = s_new
    return out


class _Stepper:
    """Marches a batch in coarse steps, each row at its own pace, locating events.

    The step of a row depends on its region: long in free flight, short in
    contact, both short enough that the switching function has at most one
    extremum per step (the hidden-crossing test relies on it). Samples are not
    taken here: every event is logged, and :func:`_fill_samples` evaluates the
    closed form at the sample times afterwards.
    """

    def __init__(self, model: LinearModel, x0: np.ndarray, v0: np.ndarray) -> None:
        self.reg = RegionCoefficients(model)
        n = len(model.batch)
        self.all = np.arange(n)
        self.x, self.v = x0.astype(float).copy(), v0.astype(float).copy()
        self.t = np.zeros(n)
        g, _ = self.reg.switching_value(self.all, self.t, self.x, self.v)
        self.region = (g > 0).astype(np.intp)
        self.log: list[tuple[np.ndarray, ...]] = []

    def set_steps(self, h_free: np.ndarray, h_contact: np.ndarray) -> None:
        """Per-row steps of each region; transition and rotation matrices follow."""
        reg = self.reg
        self.h_reg = np.stack([h_free, h_contact])  # (2, B)
        self.phi = np.stack([transition_matrix(reg.k[r], reg.c[r], self.h_reg[r]) for r in (0, 1)])
        self.rot_c = np.cos(reg.freq[None] * self.h_reg[:, :, None])  # (2, B, J)
        self.rot_s = np.sin(reg.freq[None] * self.h_reg[:, :, None])
        self._select(self.all, whole=True)
        self._anchor()

    def _select(self, rows: np.ndarray, whole: bool = False) -> None:
        """Cache each row's current-region coefficients (they change at events)."""
        reg, r = self.reg, self.region[rows]
        cur = (reg.P[r, rows], reg.Q[r, rows], reg.X[r, rows], self.phi[r, rows],
               self.rot_c[r, rows], self.rot_s[r, rows], self.h_reg[r, rows])  # fmt: skip
        if whole:
            self.Pc, self.Qc, self.Xc, self.phic, self.rcc, self.rsc, self.h = cur
            return
        for arr, val in zip(
            (self.Pc, self.Qc, self.Xc, self.phic, self.rcc, self.rsc, self.h), cur, strict=True
        ):
            arr[rows] = val

    def _anchor(self) -> None:
        ph = self.reg.freq * self.t[:, None]
        self.sn, self.cs = np.sin(ph), np.cos(ph)

    def step(self) -> None:
        """Advance every row by the step of its current region, logging events."""
        reg, r = self.reg, self.region
        f = reg.freq
        xp0, vp0, _ = _particular_sum(self.Xc, self.Pc, self.Qc, f, self.sn, self.cs)
        sn1 = self.sn * self.rcc + self.cs * self.rsc
        cs1 = self.cs * self.rcc - self.sn * self.rsc
        xp1, vp1, _ = _particular_sum(self.Xc, self.Pc, self.Qc, f, sn1, cs1)
        z0, z1 = self.x - xp0, self.v - vp0
        phi = self.phic
        x1 = phi[:, 0, 0] * z0 + phi[:, 0, 1] * z1 + xp1
        v1 = phi[:, 1, 0] * z0 + phi[:, 1, 1] * z1 + vp1
        t1 = self.t + self.h
        suspect = self._suspects(r, x1, v1, t1)
        if suspect.size:
            xs, vs, rs = self._resolve(suspect)
            x1[suspect], v1[suspect] = xs, vs
            changed = suspect[rs != self.region[suspect]]
            self.region[suspect] = rs
        self.x, self.v, self.t = x1, v1, t1
        self.sn, self.cs = sn1, cs1
        if suspect.size and changed.size:
            self._select(changed)  # after the step: the next one uses the new region

    def _suspects(self, r, x1, v1, t1) -> np.ndarray:
        """Trajectories whose switching function may change sign during the step."""
        reg, all_ = self.reg, self.all
        e1, de1 = reg.gap(all_, t1)
        d1 = x1 - e1
        g1 = np.minimum(d1, reg.beta * d1 + reg.cc * (v1 - de1))
        crossed = (g1 > 0) != (r == 1)
        # A double crossing hidden inside the step needs an extremum of G there. In
        # free flight that is a maximum of the penetration (its rate turns from
        # rising to falling) close enough to the restraint; in contact with a
        # damped restraint the force can dip anywhere, so check all of those.
        e0, de0 = reg.gap(all_, self.t)
        d0, dd0, dd1 = self.x - e0, self.v - de0, v1 - de1
        turn_free = (r == 0) & (dd0 > 0) & (dd1 <= 0)
        # With a rate linear in time the maximum is d0 + dd0^2 h / (2 (dd0 - dd1));
        # the rate is not quite linear over a coarse step, so allow three times that.
        with np.errstate(divide="ignore", invalid="ignore"):
            gain = 1.5 * self.h / (dd0 - dd1)
            reach = np.maximum(d0 + dd0 * dd0 * gain, d1 + dd1 * dd1 * gain)
        turn_free &= reach > -1e-12
        turn_contact = (r == 1) & (((dd0 < 0) & (dd1 >= 0)) | (reg.cc > 0))
        return np.flatnonzero(crossed | turn_free | turn_contact)

    def _resolve(self, idx: np.ndarray):
        """Exact march of the trajectories ``idx`` through their step with events."""
        reg = self.reg
        t, x, v = self.t[idx].copy(), self.x[idx].copy(), self.v[idx].copy()
        region = self.region[idx].copy()
        left = self.h[idx].copy()  # time remaining in the step
        active = np.arange(idx.size)
        for _ in range(MAX_EVENTS_PER_STEP):
            if active.size == 0:
                break
            seg = _Segment(reg, idx[active], region[active], t[active], x[active], v[active])
            # +1: G > 0 means "still in this region" (contact); -1 for free flight.
            sign_in = np.where(region[active] == 1, 1.0, -1.0)
            la = left[active]
            g0, r0 = seg.switching(np.zeros(active.size))
            g1, r1 = seg.switching(la)
            s_hi, g_hi = np.full(active.size, np.nan), np.full(active.size, np.nan)
            r_hi = np.zeros(active.size)  # G's rate at s_hi (0 at an interior extremum)
            out_end = g1 * sign_in <= 0
            s_hi[out_end], g_hi[out_end], r_hi[out_end] = la[out_end], g1[out_end], r1[out_end]
            # A hidden double crossing needs G's rate to point at the boundary at the
            # start of the interval and away from it at the end: check its extremum.
            turning = ~out_end & (r0 * sign_in < 0) & (r1 * sign_in > 0)
            if np.any(turning):
                sel = np.flatnonzero(turning)
                s_ext, g_ext = _interior_extremum(seg.subset(sel), la[sel], r0[sel], r1[sel])
                hit = g_ext * sign_in[sel] <= 0
                s_hi[sel[hit]], g_hi[sel[hit]] = s_ext[hit], g_ext[hit]
            has_event = np.isfinite(s_hi)
            s_go = np.where(has_event, s_hi, la)
            # On the boundary (G(0) ~ 0) with G already heading out of the region: the
            # switch is now, at s = 0; a root search would only crawl towards 0.
            now = (
                has_event
                & (np.abs(g0) <= 1e-12 * np.maximum(np.abs(g_hi), 1e-300))
                & (r0 * sign_in < 0)
            )
            s_go[now] = 0.0
            search = has_event & ~now
            if np.any(search):
                ev = np.flatnonzero(search)
                sub = seg.subset(ev)
                # Right after an event G(0) is ~0 with either sign: use the region's.
                glo = sign_in[ev] * np.maximum(np.abs(g0[ev]), 1e-300)
                tol = 1e-15 * (1.0 + np.abs(t[active[ev]]))
                guess = _hermite_starts(g0[ev], r0[ev], g_hi[ev], r_hi[ev], s_hi[ev])
                s_go[ev] = _locate_root(
                    sub, np.zeros(ev.size), s_hi[ev], glo, g_hi[ev], tol, start=guess
                )
            x[active], v[active], _ = seg.state(s_go)
            t[active] += s_go
            left[active] = np.where(has_event, np.maximum(la - s_go, 0.0), 0.0)
            ev_rows = active[has_event]
            region[ev_rows] = 1 - region[ev_rows]
            self.log.append((idx[ev_rows], t[ev_rows], x[ev_rows], v[ev_rows], region[ev_rows]))
            active = ev_rows[left[ev_rows] > 0]
        if active.size:
            # Event budget spent (chatter): finish the step in the current region
            # rather than freeze the state while time advances.
            seg = _Segment(reg, idx[active], region[active], t[active], x[active], v[active])
            x[active], v[active], _ = seg.state(left[active])
        return x, v, region


def _interior_extremum(seg: _Segment, la, r0, r1):
    """Time and value of the extremum of G inside (0, la), its rate changing sign there."""

    def rate(sg, s):
        # Newton on the rate; its slope by a forward difference of the closed form
        # is ample to locate the extremum whose *value* is then evaluated exactly.
        _, r = sg.switching(s)
        ds = 1e-7 * np.maximum(s, 1e-3)
        _, r2 = sg.switching(s + ds)
        return r, (r2 - r) / ds

    # the extremum's value is quadratically insensitive to its time: a loose tol
    tol = np.full(la.size, 1e-9)
    s = _locate_root(seg, np.zeros(la.size), la, r0, r1, tol, fun=rate)
    val, _ = seg.switching(s)
    return s, val


def closed_form_reference(
    model: LinearModel,
    x0: np.ndarray,
    v0: np.ndarray,
    t_first: np.ndarray,
    h: np.ndarray,
    n_samples: int,
) -> EngineResult:
    """Start at t=0 from (x0, v0) and sample ``n_samples`` at ``t_first + n h``.

    Returns arrays of shape ``(B, n_samples)``: ``x``, ``v`` (relative displacement
    and velocity), ``accel`` (absolute acceleration of the mass), ``contact_force``
    and ``impacts`` (contact entries during the sampling interval that ends at each
    sample), plus ``t0`` (B,), the time of the first sample.
    """
    st = _Stepper(model, x0, v0)
    st.set_steps(*coarse_steps(model))
    b = len(model.batch)
    t_last = t_first + (n_samples - 1) * h
    snap = [np.empty(b), np.empty(b), np.empty(b), np.empty(b, np.intp)]
    snapped = np.zeros(b, dtype=bool)
    first_log = 0
    for i in range(1, 10**9):
        # A row's segments start from its state at the beginning of the step that
        # reaches its first sample; every event from then on is kept.
        cross = ~snapped & (st.t + st.h >= t_first)
        if np.any(cross):
            for arr, val in zip(snap, (st.t, st.x, st.v, st.region), strict=True):
                arr[cross] = val[cross]
            snapped |= cross
        if not np.any(snapped):
            first_log = len(st.log)  # nothing before any snapshot is needed
        st.step()
        if i % REANCHOR_EVERY == 0:
            st._anchor()
        if np.all(st.t > t_last):
            break
    events = st.log[first_log:]
    return _fill_samples(st.reg, snap, events, t_first, h, n_samples)


def _fill_samples(reg: RegionCoefficients, snap, events, t_first, h, n_samples) -> EngineResult:
    """Evaluate the closed form of each segment at the sample times it covers."""
    b = t_first.size
    cat = [np.concatenate([np.arange(b)] + [e[0] for e in events])]
    for j in range(1, 5):
        cat.append(np.concatenate([snap[j - 1]] + [e[j] for e in events]))
    rows, ts, xs, vs, rs = cat
    is_event = np.arange(rows.size) >= b  # the first b segments are the snapshots
    # events logged before a row's snapshot belong to its transient: drop them
    keep = ts >= snap[0][rows]
    rows, ts, xs, vs, rs, is_event = (a[keep] for a in (rows, ts, xs, vs, rs, is_event))
    order = np.lexsort((ts, rows))
    rows, ts, xs, vs, rs, is_event = (a[order] for a in (rows, ts, xs, vs, rs, is_event))
    rs = rs.astype(np.intp)
    f = reg.freq[rows]
    P, Q, X = reg.P[rs, rows], reg.Q[rs, rows], reg.X[rs, rows]
    xp, vp, _ = _particular_sum(X, P, Q, f, np.sin(f * ts[:, None]), np.cos(f * ts[:, None]))
    z0, z1 = xs - xp, vs - vp
    k, c = reg.k[rs, rows], reg.c[rs, rows]
    sig = 0.5 * c
    disc = k - sig * sig
    all_under = bool(np.all(disc > DISC_TINY))
    root = np.sqrt(np.abs(disc))
    starts = np.searchsorted(rows, np.arange(b))
    ends = np.searchsorted(rows, np.arange(b), side="right")

    out = {key: np.empty((b, n_samples)) for key in ("x", "v", "contact_force")}
    n_idx = np.arange(n_samples)
    chunk = max(1, 2_000_000 // max(n_samples, 1))
    for c0 in range(0, b, chunk):
        cr = np.arange(c0, min(b, c0 + chunk))
        tt = t_first[cr, None] + n_idx[None, :] * h[cr, None]
        seg = np.empty(tt.shape, dtype=np.intp)
        for i, row in enumerate(cr):
            seg[i] = starts[row] - 1 + np.searchsorted(ts[starts[row] : ends[row]], tt[i], "right")
        seg, tt = seg.ravel(), tt.ravel()
        s = tt - ts[seg]
        if all_under:  # the usual case: cos, sin and exp only
            sg, rt, kk = sig[seg], root[seg], k[seg]
            decay = np.exp(-sg * s)
            cf, sf = np.cos(rt * s), np.sin(rt * s) / rt
            a0, a1 = z0[seg], z1[seg]
            xh = decay * ((cf + sg * sf) * a0 + sf * a1)
            vh = decay * (-kk * sf * a0 + (cf - sg * sf) * a1)
        else:
            phi = transition_matrix(k[seg], c[seg], s)
            xh = phi[:, 0, 0] * z0[seg] + phi[:, 0, 1] * z1[seg]
            vh = phi[:, 1, 0] * z0[seg] + phi[:, 1, 1] * z1[seg]
        fs = f[seg]
        ph = fs * tt[:, None]
        xp, vp, _ = _particular_sum(X[seg], P[seg], Q[seg], fs, np.sin(ph), np.cos(ph))
        x, v = xh + xp, vh + vp
        force = np.zeros_like(x)
        con = rs[seg] == 1
        if np.any(con):
            _, fc = reg.switching_value(rows[seg][con], tt[con], x[con], v[con])
            force[con] = np.maximum(fc, 0.0)
        shape = (cr.size, n_samples)
        out["x"][cr], out["v"][cr] = x.reshape(shape), v.reshape(shape)
        out["contact_force"][cr] = force.reshape(shape)
    # An entry at time te counts for the first sample at or after it.
    out["impacts"] = np.zeros((b, n_samples), dtype=np.int8)
    entry = is_event & (rs == 1)  # a contact already under way at the snapshot is no entry
    n_at = np.ceil((ts[entry] - t_first[rows[entry]]) / h[rows[entry]] - 1e-12).astype(np.int64)
    ok = (n_at >= 0) & (n_at < n_samples)
    np.add.at(out["impacts"], (rows[entry][ok], n_at[ok]), 1)
    # Absolute acceleration of the mass: the forces of the springs, dampers and
    # restraint; the base excitation cancels (x is relative to the table).
    out["accel"] = -(2 * reg.xi[:, None] * out["v"] + out["x"] + out["contact_force"])
    return EngineResult(t0=t_first.copy(), **out)
