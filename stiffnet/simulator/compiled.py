"""The closed-form engine: exact, event-located, compiled with numba.

Within a region (free flight or contact) eq. (12) of the paper is linear with
sinusoidal forcing, so its solution is exact for any step: subtract the particular
solution, multiply by the transition matrix, add the particular solution back
(:mod:`stiffnet.simulator.linear`). Each row marches in coarse steps (long in free
flight, short in contact: :func:`~stiffnet.simulator.linear.coarse_steps`). Contact
onset and release are located by safeguarded Newton iteration on the closed form
from a cubic Hermite start (not snapped to the sampling grid), including contacts
that begin and end inside one step (grazing), found from the interior extremum of
the switching function.

The switching function is ``G = min(x - e(t), F_c)`` with the contact force
``F_c = beta (x - e) + c_c (v - e')``: the mass is in contact exactly when
``G > 0``; with contact damping the restraint releases when the force would turn
to a pull, before the penetration is zero ("the restraint never pulls").

Within a piece of trajectory that stays in one region (a coarse step, or the part
of it between events) the first sample is the closed form evaluated at the sample
time from the piece's start state; the following samples of the piece are carried
from it by the exact one-sample transition matrix and the rotation of the forcing
phases (at most a handful of products, round-off only). One compiled loop per row,
the rows spread over numba's threads.

The numpy solver ``tests/reference_closed_form.py`` is this engine's
test oracle.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator

import numba
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


def threads() -> int:
    """Threads the parallel kernel uses (numba's, ``NUMBA_NUM_THREADS``).

    The environment is read again before numba's pool is asked (which launches it): numba
    reads ``NUMBA_NUM_THREADS`` when it is imported and after that only when it compiles. A
    Dask worker is given the variable after its process started (the nanny's ``env``,
    :data:`stiffnet.distributed.cluster.WORKER_ENV`), where a script's imports may already
    have loaded numba; a pool launched with the import-time count then makes the worker's
    first compile (a cold cache: a fresh install, changed code) fail with "Cannot set
    NUMBA_NUM_THREADS to a different value once the threads have been launched".
    """
    numba.config.reload_config()
    return int(numba.get_num_threads())


@contextlib.contextmanager
def limited_threads(n: int) -> Iterator[None]:
    """Run the parallel kernel on at most ``n`` threads inside the block (numba's pool
    launched as the environment says: :func:`threads`)."""
    before = threads()
    numba.set_num_threads(max(1, min(n, before)))
    try:
        yield
    finally:
        numba.set_num_threads(before)


def _jit(func):
    return numba.njit(cache=True, error_model="numpy")(func)


_hermite_root = _jit(hermite_root)


# ----------------------------------------------------------------- scalar helpers


@_jit
def _sgn(a):
    if a > 0.0:
        return 1.0
    if a < 0.0:
        return -1.0
    if a == 0.0:
        return 0.0
    return math.nan


@_jit
def _hom(k, sig, root, disc, s):
    """cos-like, sin/omega-like functions and the decay of the homogeneous part."""
    if disc > DISC_TINY:
        rs = root * s
        cf, sf = math.cos(rs), math.sin(rs) / root
    elif disc < -DISC_TINY:
        rs = root * s
        cf, sf = math.cosh(rs), math.sinh(rs) / root
    else:
        cf, sf = 1.0, s
    return cf, sf, math.exp(-sig * s)


@_jit
def _particular(xc, pv, qv, fv, t):
    """x_p, v_p, a_p at time t (direct trig)."""
    xp, vp, ap = 0.0, 0.0, 0.0
    for j in range(fv.size):
        ph = fv[j] * t
        sn, cs = math.sin(ph), math.cos(ph)
        ps = pv[j] * sn + qv[j] * cs
        xp += ps
        vp += fv[j] * (pv[j] * cs - qv[j] * sn)
        ap -= fv[j] * fv[j] * ps
    return xc + xp, vp, ap


@_jit
def _gap(e0, ga, gf, gp, has_gap, t):
    """e(t), e'(t), e''(t) (direct trig)."""
    if not has_gap:
        return e0, 0.0, 0.0
    e, de, dde = e0, 0.0, 0.0
    for j in range(ga.size):
        ph = gf[j] * t + gp[j]
        sn, cs = math.sin(ph), math.cos(ph)
        e += ga[j] * sn
        de += ga[j] * gf[j] * cs
        dde -= ga[j] * gf[j] * gf[j] * sn
    return e, de, dde


@_jit
def _state(s, t0, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv):
    """x, v and the region's acceleration at t0 + s from the segment's start."""
    cf, sf, decay = _hom(k, sig, root, disc, s)
    xh = decay * ((cf + sig * sf) * z0 + sf * z1)
    vh = decay * (-k * sf * z0 + (cf - sig * sf) * z1)
    xp, vp, ap = _particular(xc, pv, qv, fv, t0 + s)
    return xh + xp, vh + vp, ap - k * xh - c * vh


@_jit
def _g_rate(x, v, a, t, beta, cc, e0, ga, gf, gp, has_gap):
    """G = min(x - e, F_c) and its rate from the state, and acceleration ``a``, at t."""
    e, de, dde = _gap(e0, ga, gf, gp, has_gap, t)
    d, dd = x - e, v - de
    force = beta * d + cc * dd
    if d <= force:
        rate = dd
    else:
        rate = beta * dd + cc * (a - dde)
    return min(d, force), rate


@_jit
def _switch(s, t0, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
            beta, cc, e0, ga, gf, gp, has_gap):  # fmt: skip
    """G = min(x - e, F_c), its rate, x and v at t0 + s."""
    x, v, a = _state(s, t0, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv)
    g, rate = _g_rate(x, v, a, t0 + s, beta, cc, e0, ga, gf, gp, has_gap)
    return g, rate, x, v


@_jit
def _fun(mode, s, t0, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
         beta, cc, e0, ga, gf, gp, has_gap):  # fmt: skip
    """mode 0: (G, G'); mode 1: (G', G'') with G'' by a forward difference; then
    G, x and v at s (so that the caller need not evaluate the root again)."""
    g, r, x, v = _switch(s, t0, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
                         beta, cc, e0, ga, gf, gp, has_gap)  # fmt: skip
    if mode == 0:
        return g, r, g, x, v
    ds = 1e-7 * max(s, 1e-3)
    g2, r2, _, _ = _switch(s + ds, t0, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
                           beta, cc, e0, ga, gf, gp, has_gap)  # fmt: skip
    return r, (r2 - r) / ds, g, x, v


@_jit
def _locate(mode, lo, hi, glo, ghi, tol, has_start, start,
            t0, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
            beta, cc, e0, ga, gf, gp, has_gap):  # fmt: skip
    """Safeguarded Newton on ``[lo, hi]`` (``glo``, ``ghi`` of opposite signs).

    mode 0: a root of G; mode 1: of G'. Returns the root, the bracket's upper end,
    and whether the root is the last point evaluated, with G, x and v there.
    """
    den = ghi - glo if ghi != glo else 1.0
    s = min(max(lo - glo * (hi - lo) / den, lo), hi)
    if has_start:
        s = min(max(start, lo), hi)
    if abs(glo) <= 1e-12 * max(abs(ghi), 1e-300):
        s = 0.5 * (lo + hi)
    out = s
    known, g_s, x_s, v_s = False, 0.0, 0.0, 0.0
    for _ in range(NEWTON_ITERATIONS):
        g, dg, g_s, x_s, v_s = _fun(mode, s, t0, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
                     beta, cc, e0, ga, gf, gp, has_gap)  # fmt: skip
        if _sgn(g) == _sgn(glo):
            lo, glo = s, g
        else:
            hi, ghi = s, g
        step = g / dg
        sn = s - step
        bad = (not math.isfinite(sn)) or sn <= lo or sn >= hi
        fine = g == 0.0 or abs(step) <= tol
        if fine:
            s_new = s
        elif bad:
            s_new = 0.5 * (lo + hi)
        else:
            s_new = sn
        out = s_new
        if fine or abs(s_new - s) <= tol or hi - lo <= tol:
            known = fine
            break
        s = s_new
    return out, hi, known, g_s, x_s, v_s


@_jit
def _write_piece(row, region, tp, z0, z1, t_end, ns, n_samples, t_first, h,
                 k, sig, root, disc, xc, pv, qv, fv, hc, hs, phih,
                 beta, cc, e0, jf, ga, gcp, gsp, has_gap, xi,
                 outs, sn, cs, carry, xh, vh):  # fmt: skip
    """Samples ns, ns+1, ... with times before t_end of a segment in ``region``.

    The segment's homogeneous state is (z0, z1) at tp. With ``carry`` the
    homogeneous state (xh, vh) and the phases (sn, cs) at sample ns's time are
    known already (the previous piece was of the same segment) and no closed form
    is evaluated. Returns the next sample index, the homogeneous state at its
    time and whether that state (with sn, cs) is valid, so that the next piece of
    the same segment carries on by the one-sample recurrence alone.
    """
    if ns >= n_samples:
        return ns, xh, vh, False
    tn = t_first + ns * h
    if tn >= t_end:
        return ns, xh, vh, carry
    nj = fv.size
    if not carry:
        s = tn - tp
        cf, sf, decay = _hom(k, sig, root, disc, s)
        xh = decay * ((cf + sig * sf) * z0 + sf * z1)
        vh = decay * (-k * sf * z0 + (cf - sig * sf) * z1)
        for j in range(nj):
            ph = fv[j] * tn
            sn[j], cs[j] = math.sin(ph), math.cos(ph)
    m00, m01 = phih[region, row, 0, 0], phih[region, row, 0, 1]
    m10, m11 = phih[region, row, 1, 0], phih[region, row, 1, 1]
    while True:
        xp, vp = 0.0, 0.0
        for j in range(nj):
            xp += pv[j] * sn[j] + qv[j] * cs[j]
            vp += fv[j] * (pv[j] * cs[j] - qv[j] * sn[j])
        x, v = xh + (xc + xp), vh + vp
        force = 0.0
        if region == 1:
            e, de = e0, 0.0
            if has_gap:
                for j in range(ga.size):
                    sj, cj = sn[jf + j], cs[jf + j]
                    e += ga[j] * (sj * gcp[j] + cj * gsp[j])
                    de += ga[j] * fv[jf + j] * (cj * gcp[j] - sj * gsp[j])
            force = max(beta * (x - e) + cc * (v - de), 0.0)
        outs[0, row, ns] = x
        outs[1, row, ns] = v
        outs[2, row, ns] = force
        outs[3, row, ns] = -(2 * xi * v + x + force)
        ns += 1
        if ns >= n_samples:
            return ns, xh, vh, False
        xh, vh = m00 * xh + m01 * vh, m10 * xh + m11 * vh
        for j in range(nj):
            sn[j], cs[j] = sn[j] * hc[j] + cs[j] * hs[j], cs[j] * hc[j] - sn[j] * hs[j]
        if t_first + ns * h >= t_end:
            return ns, xh, vh, True


@_jit
def _count_entry(row, te, t_first, h, n_samples, impacts):
    n_at = math.ceil((te - t_first) / h - 1e-12)
    if n_at >= 0 and n_at < n_samples:
        impacts[row, n_at] += 1


# ----------------------------------------------------------------- one trajectory


# Why one long function: this is numba's inner loop over one trajectory (step, event
# search, region switch, sample writer). Its state lives in local scalars that numba
# keeps in registers; split into calls, that state would travel in tuples on every
# step, and the event rules are easier to compare with linear.py's read in one place.
@_jit
def _row(row, freq, P, Q, X, K, C, phi, rotc, rots, hreg, phih, hcos, hsin,
         beta_a, cc_a, e0_a, xi_a, ga_a, gf_a, gp_a, gcp_a, gsp_a, has_gap, jf,
         x0, v0, t_first, h, n_rows, outs, impacts):  # fmt: skip
    n_samples = n_rows[row]  # this row's own count: its later samples are left as they are
    fv = freq[row]
    nj = fv.size
    beta, cc, e0, xi = beta_a[row], cc_a[row], e0_a[row], xi_a[row]
    ga, gf, gp, gcp, gsp = ga_a[row], gf_a[row], gp_a[row], gcp_a[row], gsp_a[row]
    hc, hs = hcos[row], hsin[row]
    tf, hh = t_first[row], h[row]
    t_last = tf + (n_samples - 1) * hh
    ks = (K[0, row], K[1, row])
    cs_ = (C[0, row], C[1, row])
    sigs = (0.5 * cs_[0], 0.5 * cs_[1])
    discs = (ks[0] - sigs[0] * sigs[0], ks[1] - sigs[1] * sigs[1])
    roots = (math.sqrt(abs(discs[0])), math.sqrt(abs(discs[1])))

    t, x, v = 0.0, x0[row], v0[row]
    e, de, _ = _gap(e0, ga, gf, gp, has_gap, t)
    d = x - e
    region = 1 if min(d, beta * d + cc * (v - de)) > 0 else 0
    sn = np.zeros(nj)
    cs = np.ones(nj)
    sn1 = np.empty(nj)
    cs1 = np.empty(nj)
    wsn = np.empty(nj)
    wcs = np.empty(nj)
    ns = 0
    i = 0
    snapped = False
    # the samples' writer: homogeneous state at sample ns's time, carried from one
    # step to the next while the row stays in one region without events
    carry, wxh, wvh, ns_anchor = False, 0.0, 0.0, 0
    # No-contact test (underdamped free flight only): the particular solution's
    # largest reach and the lowest the gap gets, less a round-off margin.
    free_bound = abs(X[0, row])
    for j in range(nj):
        free_bound += math.sqrt(P[0, row, j] ** 2 + Q[0, row, j] ** 2)
    e_low = e0
    for j in range(ga.size):
        e_low -= abs(ga[j])
    e_low -= 1e-9 * (1.0 + abs(e_low) + free_bound)
    if not discs[0] > DISC_TINY:
        e_low = -math.inf
    while True:
        i += 1
        r = region
        H = hreg[r, row]
        pv, qv, xc = P[r, row], Q[r, row], X[r, row]
        k, c, sig, disc, root = ks[r], cs_[r], sigs[r], discs[r], roots[r]
        xp0, vp0, xp1, vp1 = 0.0, 0.0, 0.0, 0.0
        rc, rs = rotc[r, row], rots[r, row]
        for j in range(nj):
            sn1[j] = sn[j] * rc[j] + cs[j] * rs[j]
            cs1[j] = cs[j] * rc[j] - sn[j] * rs[j]
        for j in range(nj):
            ps = pv[j] * sn[j] + qv[j] * cs[j]
            xp0 += ps
            vp0 += fv[j] * (pv[j] * cs[j] - qv[j] * sn[j])
        for j in range(nj):
            ps = pv[j] * sn1[j] + qv[j] * cs1[j]
            xp1 += ps
            vp1 += fv[j] * (pv[j] * cs1[j] - qv[j] * sn1[j])
        xp0 += xc
        xp1 += xc
        z0, z1 = x - xp0, v - vp0
        x1 = phi[r, row, 0, 0] * z0 + phi[r, row, 0, 1] * z1 + xp1
        v1 = phi[r, row, 1, 0] * z0 + phi[r, row, 1, 1] * z1 + vp1
        t1 = t + H
        if not snapped and t1 >= tf:
            snapped = True  # entries before this step belong to the transient
        # Suspects: the switching function changed sign over the step, or may have
        # crossed twice inside it (an extremum of G close enough to the boundary).
        e1, de1, _ = _gap(e0, ga, gf, gp, has_gap, t1)
        d1 = x1 - e1
        g1 = min(d1, beta * d1 + cc * (v1 - de1))
        suspect = (g1 > 0) != (r == 1)
        if not suspect:
            e0t, de0, _ = _gap(e0, ga, gf, gp, has_gap, t)
            d0, dd0, dd1 = x - e0t, v - de0, v1 - de1
            if r == 0:
                if dd0 > 0 and dd1 <= 0:
                    gain = 1.5 * H / (dd0 - dd1)
                    reach = max(d0 + dd0 * dd0 * gain, d1 + dd1 * dd1 * gain)
                    suspect = reach > -1e-12
            else:
                suspect = (dd0 < 0 and dd1 >= 0) or cc > 0
        if not suspect:
            if tf + ns * hh < t1:  # the step holds samples
                if carry and ns - ns_anchor >= REANCHOR_EVERY:
                    carry = False  # re-anchor the samples' recurrence
                if not carry:
                    ns_anchor = ns
                ns, wxh, wvh, carry = _write_piece(
                    row, r, t, z0, z1, t1, ns, n_samples, tf, hh,
                    k, sig, root, disc, xc, pv, qv, fv, hc, hs, phih,
                    beta, cc, e0, jf, ga, gcp, gsp, has_gap, xi,
                    outs, wsn, wcs, carry, wxh, wvh,
                )  # fmt: skip
            x, v = x1, v1
            if r == 0 and free_bound < e_low:
                # In free flight x = x_h + x_p with |x_p| <= free_bound and |x_h| at
                # most its present amplitude (it only decays): if even their sum stays
                # below the lowest gap, the row never touches again, and its remaining
                # samples are the closed form of this one segment.
                zh0, zh1 = x1 - xp1, v1 - vp1
                wz = (zh1 + sig * zh0) / root
                if free_bound + math.sqrt(zh0 * zh0 + wz * wz) < e_low:
                    while ns < n_samples:  # re-anchored every REANCHOR_EVERY samples
                        t_end = tf + min(ns + REANCHOR_EVERY, n_samples) * hh
                        ns, _, _, _ = _write_piece(
                            row, 0, t1, zh0, zh1, t_end, ns, n_samples, tf, hh,
                            k, sig, root, disc, xc, pv, qv, fv, hc, hs, phih,
                            beta, cc, e0, jf, ga, gcp, gsp, has_gap, xi,
                            outs, wsn, wcs, False, 0.0, 0.0,
                        )  # fmt: skip
                    break
        else:
            # Exact march through the step, locating each event. G at the step's
            # ends comes from the states the step already has (no closed form).
            carry = False
            ap0, ap1 = 0.0, 0.0
            for j in range(nj):
                ap0 -= fv[j] * fv[j] * (pv[j] * sn[j] + qv[j] * cs[j])
                ap1 -= fv[j] * fv[j] * (pv[j] * sn1[j] + qv[j] * cs1[j])
            g0, r0 = _g_rate(x, v, ap0 - k * z0 - c * z1, t, beta, cc, e0, ga, gf, gp, has_gap)
            zh0, zh1 = x1 - xp1, v1 - vp1
            gl, rl = _g_rate(x1, v1, ap1 - k * zh0 - c * zh1, t1, beta, cc, e0, ga, gf, gp,
                             has_gap)  # fmt: skip
            tt, xx, vv, rr = t, x, v, r
            xl, vl = x1, v1  # the state at the step's end, in the current region
            left = H
            finished = False
            for ev in range(MAX_EVENTS_PER_STEP):
                if ev > 0:  # after an event: the new region's segment from (xx, vv)
                    pv, qv, xc = P[rr, row], Q[rr, row], X[rr, row]
                    k, c, sig, disc, root = ks[rr], cs_[rr], sigs[rr], discs[rr], roots[rr]
                    xp, vp, ap = _particular(xc, pv, qv, fv, tt)
                    z0, z1 = xx - xp, vv - vp
                    g0, r0 = _g_rate(xx, vv, ap - k * z0 - c * z1, tt, beta, cc, e0, ga, gf, gp,
                                     has_gap)  # fmt: skip
                    gl, rl, xl, vl = _switch(left, tt, z0, z1, k, c, sig, root, disc, xc, pv, qv,
                                           fv, beta, cc, e0, ga, gf, gp, has_gap)  # fmt: skip
                sign_in = 1.0 if rr == 1 else -1.0
                s_hi, g_hi, r_hi = math.nan, math.nan, 0.0
                if gl * sign_in <= 0:
                    s_hi, g_hi, r_hi = left, gl, rl
                elif r0 * sign_in < 0 and rl * sign_in > 0:
                    s_ext, _, _, _, _, _ = _locate(1, 0.0, left, r0, rl, 1e-9, False, 0.0,
                                    tt, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
                                    beta, cc, e0, ga, gf, gp, has_gap)  # fmt: skip
                    g_ext, _, _, _ = _switch(s_ext, tt, z0, z1, k, c, sig, root, disc, xc, pv,
                                             qv, fv, beta, cc, e0, ga, gf, gp, has_gap)  # fmt: skip
                    if g_ext * sign_in <= 0:
                        s_hi, g_hi = s_ext, g_ext
                if not math.isfinite(s_hi):  # no event: the rest of the step
                    if tf + ns * hh < t1:  # the piece holds samples
                        ns, _, _, _ = _write_piece(
                            row, rr, tt, z0, z1, t1, ns, n_samples, tf, hh,
                            k, sig, root, disc, xc, pv, qv, fv, hc, hs, phih,
                            beta, cc, e0, jf, ga, gcp, gsp, has_gap, xi,
                            outs, wsn, wcs, False, 0.0, 0.0,
                        )  # fmt: skip
                    xx, vv = xl, vl
                    finished = True
                    break
                x_go, v_go = xx, vv
                if abs(g0) <= 1e-12 * max(abs(g_hi), 1e-300) and r0 * sign_in < 0:
                    s_go = 0.0
                else:
                    glo = sign_in * max(abs(g0), 1e-300)
                    tol = 1e-15 * (1.0 + abs(tt))
                    guess = _hermite_root(g0, r0, g_hi, r_hi, s_hi)
                    s_go, s_out, known, g_go, x_go, v_go = _locate(
                        0, 0.0, s_hi, glo, g_hi, tol, True, guess,
                        tt, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
                        beta, cc, e0, ga, gf, gp, has_gap,
                    )  # fmt: skip
                    # Switch on the far side of the root: were the state left a
                    # round-off inside, the next region would find this root again
                    # (a spurious contact of zero length).
                    if not known:
                        g_go, _, x_go, v_go = _switch(
                            s_go, tt, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
                            beta, cc, e0, ga, gf, gp, has_gap,
                        )  # fmt: skip
                    step_out = tol
                    for _try in range(8):
                        if not g_go * sign_in > 0:
                            break
                        s_try = min(s_go + step_out, s_out)
                        g_try, _, x_try, v_try = _switch(
                            s_try, tt, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv,
                            beta, cc, e0, ga, gf, gp, has_gap,
                        )  # fmt: skip
                        if g_try * sign_in <= 0:
                            s_go, x_go, v_go = s_try, x_try, v_try
                            break
                        step_out *= 2.0
                if tf + ns * hh < tt + s_go:  # the piece holds samples
                    ns, _, _, _ = _write_piece(
                        row, rr, tt, z0, z1, tt + s_go, ns, n_samples, tf, hh,
                        k, sig, root, disc, xc, pv, qv, fv, hc, hs, phih,
                        beta, cc, e0, jf, ga, gcp, gsp, has_gap, xi,
                        outs, wsn, wcs, False, 0.0, 0.0,
                    )  # fmt: skip
                xx, vv = x_go, v_go
                tt += s_go
                left = max(left - s_go, 0.0)
                rr = 1 - rr
                if rr == 1 and snapped:
                    _count_entry(row, tt, tf, hh, n_samples, impacts)
                if not left > 0:
                    finished = True
                    break
            if not finished:
                # event budget spent (chatter): finish the step in the current region
                pv, qv, xc = P[rr, row], Q[rr, row], X[rr, row]
                k, c, sig, disc, root = ks[rr], cs_[rr], sigs[rr], discs[rr], roots[rr]
                xp, vp, _ = _particular(xc, pv, qv, fv, tt)
                z0, z1 = xx - xp, vv - vp
                if tf + ns * hh < t1:  # the piece holds samples
                    ns, _, _, _ = _write_piece(
                        row, rr, tt, z0, z1, t1, ns, n_samples, tf, hh,
                        k, sig, root, disc, xc, pv, qv, fv, hc, hs, phih,
                        beta, cc, e0, jf, ga, gcp, gsp, has_gap, xi,
                        outs, wsn, wcs, False, 0.0, 0.0,
                    )  # fmt: skip
                xx, vv, _ = _state(left, tt, z0, z1, k, c, sig, root, disc, xc, pv, qv, fv)
            x, v, region = xx, vv, rr
        t = t1
        for j in range(nj):
            sn[j], cs[j] = sn1[j], cs1[j]
        if i % REANCHOR_EVERY == 0:
            for j in range(nj):
                sn[j], cs[j] = math.sin(fv[j] * t), math.cos(fv[j] * t)
        if t > t_last and ns >= n_samples:
            break


def _kernel_serial(freq, P, Q, X, K, C, phi, rotc, rots, hreg, phih, hcos, hsin,
                   beta, cc, e0, xi, ga, gf, gp, gcp, gsp, has_gap, jf,
                   x0, v0, t_first, h, n_rows, outs, impacts):  # fmt: skip
    for row in range(x0.size):
        _row(row, freq, P, Q, X, K, C, phi, rotc, rots, hreg, phih, hcos, hsin,
             beta, cc, e0, xi, ga, gf, gp, gcp, gsp, has_gap, jf,
             x0, v0, t_first, h, n_rows, outs, impacts)  # fmt: skip


def _kernel_parallel(freq, P, Q, X, K, C, phi, rotc, rots, hreg, phih, hcos, hsin,
                     beta, cc, e0, xi, ga, gf, gp, gcp, gsp, has_gap, jf,
                     x0, v0, t_first, h, n_rows, outs, impacts):  # fmt: skip
    for row in numba.prange(x0.size):
        _row(row, freq, P, Q, X, K, C, phi, rotc, rots, hreg, phih, hcos, hsin,
             beta, cc, e0, xi, ga, gf, gp, gcp, gsp, has_gap, jf,
             x0, v0, t_first, h, n_rows, outs, impacts)  # fmt: skip


_kernel_serial = numba.njit(cache=True, error_model="numpy")(_kernel_serial)
_kernel_parallel = numba.njit(cache=True, error_model="numpy", parallel=True)(_kernel_parallel)


def _c(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def simulate_closed_form(
    model: LinearModel,
    x0: np.ndarray,
    v0: np.ndarray,
    t_first: np.ndarray,
    h: np.ndarray,
    n_samples: int,
    parallel: bool = True,
    row_samples: np.ndarray | None = None,
) -> EngineResult:
    """Start at t=0 from (x0, v0) and sample ``n_samples`` at ``t_first + n h``.

    ``x0``, ``v0``, ``t_first`` and ``h`` are per row (or broadcast). The rows run
    in parallel over numba's threads (``NUMBA_NUM_THREADS``, see
    :func:`limited_threads`) unless ``parallel`` is False. ``row_samples``: the samples
    each row needs, (B,) (at most ``n_samples``); a row stops at its own count and its
    later samples are left at 0. A row's samples do not depend on how many follow them
    (its coarse steps and events are the same), so they equal the full-length ones bit
    for bit: a campaign's rows sampled at 1 kHz need half the samples of those at 2 kHz.
    """
    reg = RegionCoefficients(model)
    b = len(model.batch)
    x0 = np.broadcast_to(np.asarray(x0, float), (b,))
    v0 = np.broadcast_to(np.asarray(v0, float), (b,))
    t_first = np.broadcast_to(np.asarray(t_first, float), (b,))
    h = np.broadcast_to(np.asarray(h, float), (b,))
    h_free, h_contact = coarse_steps(model)
    hreg = np.stack([h_free, h_contact])
    phi = np.stack([transition_matrix(reg.k[r], reg.c[r], hreg[r]) for r in (0, 1)])
    phih = np.stack([transition_matrix(reg.k[r], reg.c[r], h) for r in (0, 1)])
    freq = reg.freq
    rotc = np.cos(freq[None] * hreg[:, :, None])
    rots = np.sin(freq[None] * hreg[:, :, None])
    hcos, hsin = np.cos(freq * h[:, None]), np.sin(freq * h[:, None])
    gv = model.gap_variation
    jf = model.forcing.freq.shape[1]
    # x, v, contact force, accel: one block (zeros: pages past a row's own count are
    # never touched)
    outs = (np.empty if row_samples is None else np.zeros)((4, b, n_samples))
    impacts = np.zeros((b, n_samples), dtype=np.int8)
    n_rows = np.full(b, n_samples, dtype=np.int64)
    if row_samples is not None:
        n_rows = np.minimum(np.broadcast_to(np.asarray(row_samples, np.int64), (b,)), n_samples)
    kernel = _kernel_parallel if parallel else _kernel_serial
    kernel(
        _c(freq), _c(reg.P), _c(reg.Q), _c(reg.X), _c(reg.k), _c(reg.c), _c(phi), _c(rotc),
        _c(rots), _c(hreg), _c(phih), _c(hcos), _c(hsin), _c(reg.beta), _c(reg.cc),
        _c(reg.e0), _c(reg.xi), _c(gv.amp), _c(gv.freq), _c(gv.phase), _c(np.cos(gv.phase)),
        _c(np.sin(gv.phase)), bool(reg.has_gap_var), int(jf), _c(x0), _c(v0), _c(t_first),
        _c(h), np.ascontiguousarray(n_rows), outs, impacts,
    )  # fmt: skip
    return EngineResult(
        x=outs[0], v=outs[1], contact_force=outs[2], accel=outs[3], impacts=impacts,
        t0=np.array(t_first, dtype=float),
    )  # fmt: skip
