"""Exact, event-located, batched solver of the piecewise-linear impact oscillator.

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

from dataclasses import dataclass

import numpy as np

from stiffnet.effects.base import Sinusoids
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.linear import particular_coefficients, transition_matrix

_MAX_EVENTS_PER_STEP = 12
_NEWTON_ITERS = 60
_REANCHOR_EVERY = 512  # exact trig every so many steps bounds the rotation round-off


@dataclass
class LinearModel:
    """The piecewise-linear model of a batch: forcing, gap and contact terms."""

    batch: OscillatorBatch
    forcing: Sinusoids  # F(t), includes a w^2 sin(w t)
    gap_variation: Sinusoids  # e(t) - e
    contact_damping: np.ndarray  # c_c, (B,)


class _Regions:
    """Per-region constants: particular-solution coefficients and step matrices."""

    def __init__(self, model: LinearModel) -> None:
        b = model.batch
        beta, xi, cc = b.beta, b.damping, model.contact_damping
        self.beta, self.cc, self.e0 = beta, cc, b.gap
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


class _Segment:
    """Closed-form solution from a state, staying in one region, for many rows.

    Precomputes everything that does not depend on the elapsed time ``s`` so the
    Newton iterations of event location cost one trig evaluation each.
    """

    def __init__(self, reg: _Regions, idx, region, t0, x0, v0) -> None:
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
        self.all_under = bool(np.all(disc > 1e-12))
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


def _locate_root(seg, lo, hi, glo, ghi, tol, fun=None):
    """Safeguarded Newton: a root of G on [lo, hi] where glo and ghi differ in sign.

    ``seg`` gives ``switching(s) -> (G, G')`` (or ``fun(seg, s)`` does) and
    ``subset(rows)``; rows that have converged drop out of the iteration.
    """
    fun = fun or (lambda sg, x: sg.switching(x))
    s = np.clip(lo - glo * (hi - lo) / np.where(ghi != glo, ghi - glo, 1.0), lo, hi)
    # Starting on the boundary (right after an event, G(lo) ~ 0) the secant guess is
    # lo itself, where G may be exactly 0: bisect first so that point is not taken
    # for the root and the region does not flip back and forth.
    on_boundary = np.abs(glo) <= 1e-12 * np.maximum(np.abs(ghi), 1e-300)
    s = np.where(on_boundary, 0.5 * (lo + hi), s)
    out = s.copy()
    rows = np.arange(s.size)
    for _ in range(_NEWTON_ITERS):
        g, dg = fun(seg, s)
        left = np.sign(g) == np.sign(glo)
        lo, glo = np.where(left, s, lo), np.where(left, g, glo)
        hi, ghi = np.where(left, hi, s), np.where(left, ghi, g)
        with np.errstate(divide="ignore", invalid="ignore"):
            sn = s - g / dg
        bad = ~np.isfinite(sn) | (sn <= lo) | (sn >= hi)
        exact = g == 0  # keep an exact root: the bracket has collapsed onto it
        s_new = np.where(exact, s, np.where(bad, 0.5 * (lo + hi), sn))
        done = exact | (np.abs(s_new - s) <= tol) | (hi - lo <= tol)
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
    """Marches a batch over a uniform grid, handling events inside steps."""

    def __init__(self, model: LinearModel, x0: np.ndarray, v0: np.ndarray) -> None:
        self.reg = _Regions(model)
        n = len(model.batch)
        self.all = np.arange(n)
        self.x, self.v = x0.astype(float).copy(), v0.astype(float).copy()
        self.t = np.zeros(n)
        g, _ = self.reg.switching_value(self.all, self.t, self.x, self.v)
        self.region = (g > 0).astype(np.intp)
        self._select(self.all)

    def _select(self, rows: np.ndarray) -> None:
        """Cache the coefficients of each row's current region (changes at events)."""
        reg, r = self.reg, self.region[rows]
        if rows is self.all:
            self.Pc, self.Qc, self.Xc = reg.P[r, rows], reg.Q[r, rows], reg.X[r, rows]
            if hasattr(self, "phi"):
                self.phic = self.phi[r, rows]
            return
        self.Pc[rows], self.Qc[rows], self.Xc[rows] = reg.P[r, rows], reg.Q[r, rows], reg.X[r, rows]
        self.phic[rows] = self.phi[r, rows]

    # -- grid set-up -------------------------------------------------------
    def set_step(self, h: np.ndarray) -> None:
        reg = self.reg
        self.h = h
        self.phi = np.stack([transition_matrix(reg.k[r], reg.c[r], h) for r in (0, 1)])
        self.phic = self.phi[self.region, self.all]
        self.rot_c = np.cos(reg.freq * h[:, None])
        self.rot_s = np.sin(reg.freq * h[:, None])
        self._anchor()

    def _anchor(self) -> None:
        ph = self.reg.freq * self.t[:, None]
        self.sn, self.cs = np.sin(ph), np.cos(ph)

    # -- one step ------------------------------------------------------------
    def step(self) -> np.ndarray:
        """Advance every trajectory by its h. Returns the number of contact entries."""
        reg, all_, r = self.reg, self.all, self.region
        f = reg.freq
        xp0, vp0, _ = _particular_sum(self.Xc, self.Pc, self.Qc, f, self.sn, self.cs)
        sn1 = self.sn * self.rot_c + self.cs * self.rot_s
        cs1 = self.cs * self.rot_c - self.sn * self.rot_s
        xp1, vp1, _ = _particular_sum(self.Xc, self.Pc, self.Qc, f, sn1, cs1)
        z0, z1 = self.x - xp0, self.v - vp0
        phi = self.phic
        x1 = phi[:, 0, 0] * z0 + phi[:, 0, 1] * z1 + xp1
        v1 = phi[:, 1, 0] * z0 + phi[:, 1, 1] * z1 + vp1
        t1 = self.t + self.h
        entries = np.zeros(all_.size, dtype=np.int32)
        suspect = self._suspects(r, x1, v1, t1)
        if suspect.size:
            xs, vs, rs, ent = self._resolve(suspect)
            x1[suspect], v1[suspect] = xs, vs
            changed = suspect[rs != self.region[suspect]]
            self.region[suspect] = rs
            entries[suspect] = ent
            if changed.size:
                self._select(changed)
        self.x, self.v, self.t = x1, v1, t1
        self.sn, self.cs = sn1, cs1
        return entries

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
        # Over one short step the rate is nearly linear in time, so the maximum is
        # d0 + dd0^2 h / (2 (dd0 - dd1)); twice that margin keeps the filter safe.
        with np.errstate(divide="ignore", invalid="ignore"):
            reach = d0 + dd0 * dd0 * self.h / (dd0 - dd1)
        turn_free &= reach > -1e-12
        turn_contact = (r == 1) & (((dd0 < 0) & (dd1 >= 0)) | (reg.cc > 0))
        return np.flatnonzero(crossed | turn_free | turn_contact)

    def _resolve(self, idx: np.ndarray):
        """Exact march of the trajectories ``idx`` through their step with events."""
        reg = self.reg
        t, x, v = self.t[idx].copy(), self.x[idx].copy(), self.v[idx].copy()
        region = self.region[idx].copy()
        left = self.h[idx].copy()  # time remaining in the step
        entries = np.zeros(idx.size, dtype=np.int32)
        active = np.arange(idx.size)
        for _ in range(_MAX_EVENTS_PER_STEP):
            if active.size == 0:
                break
            seg = _Segment(reg, idx[active], region[active], t[active], x[active], v[active])
            # +1: G > 0 means "still in this region" (contact); -1 for free flight.
            sign_in = np.where(region[active] == 1, 1.0, -1.0)
            la = left[active]
            g0, r0 = seg.switching(np.zeros(active.size))
            g1, r1 = seg.switching(la)
            s_hi, g_hi = np.full(active.size, np.nan), np.full(active.size, np.nan)
            out_end = g1 * sign_in <= 0
            s_hi[out_end], g_hi[out_end] = la[out_end], g1[out_end]
            # A hidden double crossing needs G's rate to point at the boundary at the
            # start of the interval and away from it at the end: check its extremum.
            turning = ~out_end & (r0 * sign_in < 0) & (r1 * sign_in > 0)
            if np.any(turning):
                sel = np.flatnonzero(turning)
                a = active[sel]
                sub = _Segment(reg, idx[a], region[a], t[a], x[a], v[a])
                s_ext, g_ext = _interior_extremum(sub, la[sel], r0[sel], r1[sel])
                hit = g_ext * sign_in[sel] <= 0
                s_hi[sel[hit]], g_hi[sel[hit]] = s_ext[hit], g_ext[hit]
            has_event = np.isfinite(s_hi)
            s_go = np.where(has_event, s_hi, la)
            if np.any(has_event):
                ev = np.flatnonzero(has_event)
                sub = _Segment(reg, idx[active[ev]], region[active[ev]], t[active[ev]],
                               x[active[ev]], v[active[ev]])  # fmt: skip
                # Right after an event G(0) is ~0 with either sign: use the region's.
                glo = sign_in[ev] * np.maximum(np.abs(g0[ev]), 1e-300)
                tol = 1e-15 * (1.0 + np.abs(t[active[ev]]))
                s_go[ev] = _locate_root(sub, np.zeros(ev.size), s_hi[ev], glo, g_hi[ev], tol)
            x[active], v[active], _ = seg.state(s_go)
            t[active] += s_go
            left[active] = np.where(has_event, np.maximum(la - s_go, 0.0), 0.0)
            ev_rows = active[has_event]
            entries[ev_rows] += region[ev_rows] == 0
            region[ev_rows] = 1 - region[ev_rows]
            active = ev_rows[left[ev_rows] > 0]
        if active.size:
            # Event budget spent (chatter): finish the step in the current region
            # rather than freeze the state while time advances.
            seg = _Segment(reg, idx[active], region[active], t[active], x[active], v[active])
            x[active], v[active], _ = seg.state(left[active])
        return x, v, region, entries


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


def simulate_linear(
    model: LinearModel,
    x0: np.ndarray,
    v0: np.ndarray,
    h_transient: np.ndarray,
    n_transient: int,
    h: np.ndarray,
    n_samples: int,
    substeps: int = 1,
) -> dict[str, np.ndarray]:
    """March ``n_transient`` steps of ``h_transient``, then record ``n_samples`` of ``h``.

    ``substeps`` internal steps are taken per sample (event detection assumes at
    most one extremum of the switching function per internal step).

    Returns arrays of shape ``(B, n_samples)``: ``x``, ``v`` (relative displacement
    and velocity), ``accel`` (absolute acceleration of the mass), ``contact_force``
    and ``impacts`` (contact entries during the sampling interval that ends at each
    sample), plus ``t0`` (B,), the time of the first sample.
    """
    st = _Stepper(model, x0, v0)
    if n_transient > 0:
        st.set_step(h_transient)
        for i in range(n_transient):
            if i and i % _REANCHOR_EVERY == 0:
                st._anchor()
            st.step()
    b = len(model.batch)
    # (N, B) while recording: each sample writes one contiguous row
    out = {k: np.empty((n_samples, b)) for k in ("x", "v", "contact_force")}
    out["impacts"] = np.zeros((n_samples, b), dtype=np.int8)
    st.set_step(h / substeps)
    t0 = st.t + h
    k = 0
    for i in range(n_samples):
        for _ in range(substeps):
            k += 1
            if k % _REANCHOR_EVERY == 0:
                st._anchor()
            out["impacts"][i] += st.step()
        out["x"][i], out["v"][i] = st.x, st.v
        out["contact_force"][i] = st.region  # contact flag now, force below
    out = {key: val.T for key, val in out.items()}  # (B, N) views, no copy
    in_contact = out["contact_force"] > 0
    if np.any(in_contact):
        rows = np.nonzero(in_contact)[0]
        tt = t0[rows] + np.nonzero(in_contact)[1] * h[rows]
        _, force = st.reg.switching_value(rows, tt, out["x"][in_contact], out["v"][in_contact])
        out["contact_force"][in_contact] = np.maximum(force, 0.0)
    # Absolute acceleration of the mass: the forces of the springs, dampers and
    # restraint; the base excitation cancels (x is relative to the table).
    out["accel"] = -(2 * model.batch.damping[:, None] * out["v"] + out["x"] + out["contact_force"])
    out["t0"] = t0
    return out
