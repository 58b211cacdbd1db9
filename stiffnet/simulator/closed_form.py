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

    def particular(self, region: np.ndarray, idx: np.ndarray, t: np.ndarray):
        """x_p, v_p, a_p at times t for trajectories idx in the given regions."""
        f = self.freq[idx]
        ph = f * t[:, None]
        sn, cs = np.sin(ph), np.cos(ph)
        return self.particular_from_trig(region, idx, f, sn, cs)

    def particular_from_trig(self, region, idx, f, sn, cs):
        p = self.P[region, idx]
        q = self.Q[region, idx]
        ps = p * sn + q * cs
        xp = self.X[region, idx] + ps.sum(axis=1)
        vp = (f * (p * cs - q * sn)).sum(axis=1)
        ap = -(f * f * ps).sum(axis=1)
        return xp, vp, ap

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

    def switching(self, idx, t, x, v, region, want_rate: bool = True):
        """G = min(x - e, F_c), its time derivative, and the contact force."""
        e, de = self.gap(idx, t)
        beta, cc = self.beta[idx], self.cc[idx]
        d, dd = x - e, v - de
        force = beta * d + cc * dd
        g = np.minimum(d, force)
        if not want_rate:
            return g, None, force
        k, c = self.k[region, idx], self.c[region, idx]
        xp, vp, ap = self.particular(region, idx, t)
        acc = ap - k * (x - xp) - c * (v - vp)  # homogeneous part + particular
        ddd = acc - self.gap_accel(idx, t)
        rate = np.where(d <= force, dd, beta * dd + cc * ddd)
        return g, rate, force


def _propagate(reg: _Regions, idx, region, t0, x0, v0, s):
    """State at t0 + s from (x0, v0) at t0, staying in ``region``."""
    xp0, vp0, _ = reg.particular(region, idx, t0)
    phi = transition_matrix(reg.k[region, idx], reg.c[region, idx], s)
    z0, z1 = x0 - xp0, v0 - vp0
    xp1, vp1, _ = reg.particular(region, idx, t0 + s)
    x = phi[:, 0, 0] * z0 + phi[:, 0, 1] * z1 + xp1
    v = phi[:, 1, 0] * z0 + phi[:, 1, 1] * z1 + vp1
    return x, v


def _locate_root(fun, lo, hi, glo, ghi, tol):
    """Safeguarded Newton: a root of fun on [lo, hi] where glo, ghi differ in sign."""
    s = np.clip(lo - glo * (hi - lo) / np.where(ghi != glo, ghi - glo, 1.0), lo, hi)
    for _ in range(_NEWTON_ITERS):
        g, dg = fun(s)
        left = np.sign(g) == np.sign(glo)
        lo, glo = np.where(left, s, lo), np.where(left, g, glo)
        hi, ghi = np.where(left, hi, s), np.where(left, ghi, g)
        with np.errstate(divide="ignore", invalid="ignore"):
            sn = s - g / dg
        bad = ~np.isfinite(sn) | (sn <= lo) | (sn >= hi)
        exact = g == 0  # keep an exact root: the bracket has collapsed onto it
        s_new = np.where(exact, s, np.where(bad, 0.5 * (lo + hi), sn))
        done = exact | (np.abs(s_new - s) <= tol) | (hi - lo <= tol)
        s = s_new
        if np.all(done):
            break
    return s


class _Stepper:
    """Marches a batch over a uniform grid, handling events inside steps."""

    def __init__(self, model: LinearModel, x0: np.ndarray, v0: np.ndarray) -> None:
        self.reg = _Regions(model)
        n = len(model.batch)
        self.all = np.arange(n)
        self.x, self.v = x0.astype(float).copy(), v0.astype(float).copy()
        self.t = np.zeros(n)
        g, _, _ = self.reg.switching(self.all, self.t, self.x, self.v, np.zeros(n, int), False)
        self.region = (g > 0).astype(np.intp)

    # -- grid set-up -------------------------------------------------------
    def set_step(self, h: np.ndarray) -> None:
        reg = self.reg
        self.h = h
        self.phi = np.stack([transition_matrix(reg.k[r], reg.c[r], h) for r in (0, 1)])
        self.rot_c = np.cos(reg.freq * h[:, None])
        self.rot_s = np.sin(reg.freq * h[:, None])
        self._anchor()

    def _anchor(self) -> None:
        ph = self.reg.freq * self.t[:, None]
        self.sn, self.cs = np.sin(ph), np.cos(ph)

    # -- one step ------------------------------------------------------------
    def step(self, record_entries: bool) -> np.ndarray:
        """Advance every trajectory by its h. Returns the number of contact entries."""
        reg, all_, r = self.reg, self.all, self.region
        f = reg.freq
        xp0, vp0, _ = reg.particular_from_trig(r, all_, f, self.sn, self.cs)
        sn1 = self.sn * self.rot_c + self.cs * self.rot_s
        cs1 = self.cs * self.rot_c - self.sn * self.rot_s
        xp1, vp1, _ = reg.particular_from_trig(r, all_, f, sn1, cs1)
        z0, z1 = self.x - xp0, self.v - vp0
        phi = self.phi[r, all_]
        x1 = phi[:, 0, 0] * z0 + phi[:, 0, 1] * z1 + xp1
        v1 = phi[:, 1, 0] * z0 + phi[:, 1, 1] * z1 + vp1
        t1 = self.t + self.h
        entries = np.zeros(all_.size, dtype=np.int32)
        suspect = self._suspects(r, x1, v1, t1)
        if suspect.size:
            xs, vs, rs, ent = self._resolve(suspect)
            x1[suspect], v1[suspect] = xs, vs
            self.region[suspect] = rs
            entries[suspect] = ent
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
        reach = np.maximum(d0, d1) + (np.abs(dd0) + np.abs(dd1)) * self.h
        turn_free = (r == 0) & (dd0 > 0) & (dd1 <= 0) & (reach > 0)
        turn_contact = (r == 1) & (((dd0 < 0) & (dd1 >= 0)) | (reg.cc > 0))
        return np.flatnonzero(crossed | turn_free | turn_contact)

    def _resolve(self, idx: np.ndarray):
        """Exact march of the trajectories ``idx`` through their step with events."""
        reg = self.reg
        t, x, v = self.t[idx].copy(), self.x[idx].copy(), self.v[idx].copy()
        region = self.region[idx].copy()
        left = self.h[idx].copy()  # time remaining in the step
        entries = np.zeros(idx.size, dtype=np.int32)

        def make_g(sel):
            """G(s) and G'(s) from the current state of local trajectories ``sel``."""
            gi, ts, xs, vs, rs = idx[sel], t[sel].copy(), x[sel].copy(), v[sel].copy(), region[sel]

            def g(s):
                xs1, vs1 = _propagate(reg, gi, rs, ts, xs, vs, s)
                val, rate, _ = reg.switching(gi, ts + s, xs1, vs1, rs)
                return val, rate

            return g

        active = np.arange(idx.size)
        for _ in range(_MAX_EVENTS_PER_STEP):
            if active.size == 0:
                break
            # +1: G > 0 means "still in this region" (contact); -1 for free flight.
            sign_in = np.where(region[active] == 1, 1.0, -1.0)
            la = left[active]
            g = make_g(active)
            g0, r0 = g(np.zeros(active.size))
            g1, r1 = g(la)
            s_hi, g_hi = np.full(active.size, np.nan), np.full(active.size, np.nan)
            out_end = g1 * sign_in <= 0
            s_hi[out_end], g_hi[out_end] = la[out_end], g1[out_end]
            # A hidden double crossing needs G's rate to point at the boundary at the
            # start of the interval and away from it at the end: check its extremum.
            turning = ~out_end & (r0 * sign_in < 0) & (r1 * sign_in > 0)
            if np.any(turning):
                sel = np.flatnonzero(turning)
                s_ext, g_ext = _interior_extremum(make_g(active[sel]), la[sel], r0[sel], r1[sel])
                hit = g_ext * sign_in[sel] <= 0
                s_hi[sel[hit]], g_hi[sel[hit]] = s_ext[hit], g_ext[hit]
            has_event = np.isfinite(s_hi)
            quiet = active[~has_event]
            if quiet.size:
                x[quiet], v[quiet] = _propagate(
                    reg, idx[quiet], region[quiet], t[quiet], x[quiet], v[quiet], left[quiet]
                )
                t[quiet] += left[quiet]
                left[quiet] = 0.0
            if not np.any(has_event):
                break
            ev = active[has_event]
            si = sign_in[has_event]
            # Right after an event G(0) is ~0 with an arbitrary sign: use the region's sign.
            glo = si * np.maximum(np.abs(g0[has_event]), 1e-300)
            tol = 1e-15 * (1.0 + np.abs(t[ev]))
            s_star = _locate_root(
                make_g(ev), np.zeros(ev.size), s_hi[has_event], glo, g_hi[has_event], tol
            )
            x[ev], v[ev] = _propagate(reg, idx[ev], region[ev], t[ev], x[ev], v[ev], s_star)
            t[ev] += s_star
            left[ev] = np.maximum(left[ev] - s_star, 0.0)
            entries[ev] += region[ev] == 0
            region[ev] = 1 - region[ev]
            active = ev[left[ev] > 0]
        return x, v, region, entries


def _interior_extremum(g, la, r0, r1):
    """Time and value of the extremum of G inside (0, la), rate changing sign there."""

    def rate(s):
        # Newton on the rate; its slope by a forward difference of the closed form
        # is ample to locate the extremum whose *value* is then evaluated exactly.
        _, r = g(s)
        ds = 1e-7 * np.maximum(la, 1e-3)
        _, r2 = g(s + ds)
        return r, (r2 - r) / ds

    s = _locate_root(rate, np.zeros(la.size), la, r0, r1, 1e-13)
    val, _ = g(s)
    return s, val


def simulate_linear(
    model: LinearModel,
    x0: np.ndarray,
    v0: np.ndarray,
    h_transient: np.ndarray,
    n_transient: int,
    h: np.ndarray,
    n_samples: int,
) -> dict[str, np.ndarray]:
    """March ``n_transient`` steps of ``h_transient``, then record ``n_samples`` of ``h``.

    Returns arrays of shape ``(B, n_samples)``: ``x``, ``v`` (relative displacement
    and velocity), ``accel`` (absolute acceleration of the mass), ``contact_force``
    and ``impacts`` (contact entries during the step that ends at each sample),
    plus ``t0`` (B,), the time of the first sample.
    """
    st = _Stepper(model, x0, v0)
    if n_transient > 0:
        st.set_step(h_transient)
        for i in range(n_transient):
            if i and i % _REANCHOR_EVERY == 0:
                st._anchor()
            st.step(False)
    b = len(model.batch)
    out = {k: np.empty((b, n_samples)) for k in ("x", "v", "contact_force")}
    out["impacts"] = np.zeros((b, n_samples), dtype=np.int8)
    st.set_step(h)
    t0 = st.t + h
    for i in range(n_samples):
        if i and i % _REANCHOR_EVERY == 0:
            st._anchor()
        out["impacts"][:, i] = st.step(True)
        out["x"][:, i], out["v"][:, i] = st.x, st.v
        _, _, force = st.reg.switching(st.all, st.t, st.x, st.v, st.region, False)
        out["contact_force"][:, i] = np.where(st.region == 1, force, 0.0)
    # Absolute acceleration of the mass: the forces of the springs, dampers and
    # restraint; the base excitation cancels (x is relative to the table).
    out["accel"] = -(2 * model.batch.damping[:, None] * out["v"] + out["x"] + out["contact_force"])
    out["t0"] = t0
    return out
