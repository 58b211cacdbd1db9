"""One sensor chain fitted jointly to the impacts of a campaign's recordings.

A campaign's recordings share their accelerometer, so the chain is one set of numbers
(mounted resonance and damping, low-pass corner and order) while every recording has its
own contact (its beta, its damping). :func:`~stiffnet.restoring_force.chain.fit_chain`
identifies a chain per recording, and only where the record's contact law needs one; the
median of those fits (:func:`~stiffnet.restoring_force.chain.shared_chain`) is as good as
its worst recordings: on the independent rig's campaigns the pooled low-passes were
14-22 % off (145 Hz of order 1 for a true 187 Hz of order 2), because one record's impacts
barely tell a low-pass's corner from its order. Fitted to the impacts of every recording
at once (:func:`fit_joint_chain`: the chain shared, each recording's contact frequency,
damping and offset and each impact's onset, size and baseline its own), contacts of
different stiffness see the same filter at different points of its response, which pins
the corner and the order down together.

The pulse model and its residuals are :mod:`~stiffnet.restoring_force.chain`'s
(``_residuals``: the Kelvin-Voigt pulse through the chain, each impact's size and linear
baseline projected out); the impacts are the ones the chain fit of each recording reads
(:func:`impact_pulses`). Numpy/scipy only (the predictor's campaign chain imports it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from stiffnet.errors import SignalError
from stiffnet.restoring_force.chain import (
    COVERAGE,
    MAX_RESONANCE_DAMPING,
    MIN_RESONANCE_DAMPING,
    ORDERS,
    SensorChain,
    _bounds,
    _chain_windows,
    _grid_best,
    _residuals,
    _Windows,
)
from stiffnet.restoring_force.estimate import (
    CHAIN_FIT_WHEN_NEEDED,
    _auto_map,
    _periodic_record,
    _record_and_lines,
)
from stiffnet.restoring_force.free_flight import CONTACT_SIGMAS
from stiffnet.restoring_force.sensor import RINGING_WINDOW, ringing_mode

#: Function evaluations of each joint least-squares start (the shared chain and every
#: recording's contact move together; a start from the pooled chain converges in 10-30).
JOINT_NFEV = 60
#: Function evaluations of each recording's own contact fit behind the start's chain.
CONTACT_NFEV = 20
#: Starts of the low-pass corner, as multiples of the pooled one (a median of per-recording
#: fits is 14-22 % off on the rig's campaigns, either side).
CORNER_STARTS = (0.8, 1.0, 1.25)


@dataclass
class ImpactPulses:
    """One recording's impacts as the chain fit reads them (the free-flight law's residual
    force around each impact), with its rate, natural frequency and the contact frequency of
    its plain map (a start)."""

    win: _Windows
    fs_hz: float
    fn_hz: float
    contact_hz: float | None


def impact_pulses(
    accel: np.ndarray,
    fs_hz: float,
    natural_frequency_hz: float,
    max_periods: float | None = 24.0,
) -> ImpactPulses | None:
    """The impacts of one recording for :func:`fit_joint_chain`: its plain map's residual
    force around each impact (the high-pass corner fitted as the restoring-force estimate
    fits it, the forcing line of best free-flight fit), or None where the record shows fewer
    than 3 usable impacts or cannot be read."""
    try:
        a, lines = _record_and_lines(accel, fs_hz, natural_frequency_hz, None, max_periods)
    except (SignalError, ValueError):
        return None
    best = None
    for ff in lines:
        try:
            args, _ = _periodic_record(a, fs_hz, ff, natural_frequency_hz, max_periods)
        except SignalError:
            continue
        m, _ = _auto_map(*args, None, CHAIN_FIT_WHEN_NEEDED)
        if best is None or m.fit.r2 > best[0].fit.r2:
            best = (m, ff, args)
    if best is None or best[0].labels is None:
        return None
    m, ff, (y, dtau, tau, use, period, k_given) = best
    natural = period / np.sqrt(m.fit.stiffness) if m.fit.stiffness > 0 else period
    fn_hz = fs_hz / natural
    ring = ringing_mode(m.fit.force, m.fit.contact, int(RINGING_WINDOW * natural))
    ring_hz = ring[0] * fs_hz / (2 * np.pi) if ring is not None and ring[2] > 0.5 else None
    hint = ff * float(np.sqrt(m.law.stiffness + m.fit.stiffness)) if m.law else None
    core = (m.fit.force > CONTACT_SIGMAS * m.fit.sigma) & use
    win = _chain_windows(m.fit.force, core, fs_hz, fn_hz, m.spc, ring_hz, hint)
    return None if win is None else ImpactPulses(win, fs_hz, fn_hz, hint)


def _recording_theta(shared: np.ndarray, own: np.ndarray, onsets: np.ndarray, structure):
    """One recording's parameters for ``chain._residuals`` from the shared chain (log
    resonance Hz and damping, log corner) and its own contact (log Hz, log zeta, offset):
    the resonance enters ``_residuals`` relative to the recording's contact."""
    th = list(own)
    k = 0
    if structure[0]:
        th += [shared[0] - own[0], shared[1]]
        k = 2
    if structure[1]:
        th += [shared[k]]
    return np.r_[th, onsets]


def _n_shared(structure) -> int:
    return 2 * bool(structure[0]) + bool(structure[1])


class _JointProblem:
    """The joint least squares of one chain structure over several recordings' impacts:
    parameters ``[shared chain | each recording's contact (3) | every impact's onset]``."""

    def __init__(self, pulses: Sequence[ImpactPulses], structure):
        self.pulses, self.structure = list(pulses), structure
        self.ns = _n_shared(structure)
        self.counts = [p.win.n for p in self.pulses]
        self.sizes = [p.win.r.size for p in self.pulses]
        fs_low = min(p.fs_hz for p in self.pulses)
        fn = min(p.fn_hz for p in self.pulses)
        lo, hi = [], []
        if structure[0]:
            lo += [np.log(2.0 * fn), np.log(MIN_RESONANCE_DAMPING)]
            hi += [np.log(0.49 * fs_low), np.log(MAX_RESONANCE_DAMPING)]
        if structure[1]:
            lo += [np.log(0.5 * fn)]
            hi += [np.log(0.49 * fs_low)]
        own_lo, own_hi, t_lo, t_hi = [], [], [], []
        for p in self.pulses:
            b_lo, b_hi = _bounds(p.win, p.fs_hz, p.fn_hz, (False, 0))
            own_lo += list(b_lo[:3])
            own_hi += list(b_hi[:3])
            t_lo += list(b_lo[3:])
            t_hi += list(b_hi[3:])
        self.lower = np.array(lo + own_lo + t_lo)
        self.upper = np.array(hi + own_hi + t_hi)

    def split(self, x: np.ndarray):
        """(shared, per recording (own, onsets)) of the parameter vector."""
        shared = x[: self.ns]
        own = x[self.ns : self.ns + 3 * len(self.pulses)].reshape(-1, 3)
        onsets = np.split(x[self.ns + 3 * len(self.pulses) :], np.cumsum(self.counts)[:-1])
        return shared, list(zip(own, onsets, strict=True))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        shared, parts = self.split(x)
        return np.concatenate([
            _residuals(_recording_theta(shared, own, t0, self.structure), p.win, p.fs_hz,
                       self.structure)
            for p, (own, t0) in zip(self.pulses, parts, strict=True)
        ])  # fmt: skip

    def sparsity(self) -> np.ndarray:
        """Which residuals each parameter moves: the chain all, a contact its recording's, an
        onset its impact's window."""
        n_own = 3 * len(self.pulses)
        total = self.ns + n_own + sum(self.counts)
        out = np.zeros((sum(self.sizes), total), dtype=int)
        out[:, : self.ns] = 1
        row, onset = 0, self.ns + n_own
        for j, p in enumerate(self.pulses):
            rows = slice(row, row + p.win.r.size)
            out[rows, self.ns + 3 * j : self.ns + 3 * j + 3] = 1
            impact = np.repeat(np.arange(p.win.n), p.win.length)
            out[row + np.arange(p.win.r.size), onset + impact] = 1
            row += p.win.r.size
            onset += p.win.n
        return out

    def solve(self, starts: list[np.ndarray], max_nfev: int = JOINT_NFEV):
        """The best least-squares solution over `starts`: (x, sse, jacobian)."""
        best = None
        sparsity = self.sparsity()
        for start in starts:
            sol = optimize.least_squares(
                self.residuals, np.clip(start, self.lower + 1e-9, self.upper - 1e-9),
                bounds=(self.lower, self.upper), x_scale="jac", max_nfev=max_nfev,
                diff_step=1e-4, jac_sparsity=sparsity,
            )  # fmt: skip
            sse = float(np.sum(sol.fun**2))
            if best is None or sse < best[1]:
                best = (sol.x, sse, sol.jac)
        return best


def _contact_start(p: ImpactPulses, structure, shared: np.ndarray) -> np.ndarray:
    """One recording's contact (log Hz, log zeta, offset) and onsets behind the start's
    chain: the best of a grid of contact frequencies (and its plain map's), then a short
    least squares of the contact alone with the chain held."""
    lo, hi = _bounds(p.win, p.fs_hz, p.fn_hz, (False, 0))
    timing = np.full(p.win.n, p.win.pre - 0.5)
    grid = list(np.geomspace(np.exp(lo[0]) * 1.01, 0.4 * p.fs_hz, 12))
    if p.contact_hz:
        grid.append(float(np.clip(p.contact_hz, np.exp(lo[0]) * 1.01, 0.4 * p.fs_hz)))
    thetas = [_recording_theta(shared, [np.log(c), np.log(0.1), 0.0], timing, structure)
              for c in grid]  # fmt: skip
    c0 = _grid_best(p.win, p.fs_hz, structure, thetas, 0)
    x0 = np.r_[np.log(c0), np.log(0.1), 0.0, timing]
    lower, upper = np.r_[lo[:3], lo[3:]], np.r_[hi[:3], hi[3:]]

    def resid(x: np.ndarray) -> np.ndarray:
        return _residuals(_recording_theta(shared, x[:3], x[3:], structure), p.win, p.fs_hz,
                          structure)  # fmt: skip

    sol = optimize.least_squares(resid, np.clip(x0, lower + 1e-9, upper - 1e-9),
                                 bounds=(lower, upper), x_scale="jac", max_nfev=CONTACT_NFEV,
                                 diff_step=1e-4)  # fmt: skip
    return sol.x


def _start(problem: _JointProblem, shared: np.ndarray) -> np.ndarray:
    """The joint parameters from a shared chain, each recording's contact fitted behind it."""
    own, onsets = [], []
    for p in problem.pulses:
        x = _contact_start(p, problem.structure, shared)
        own.append(x[:3])
        onsets.append(x[3:])
    return np.r_[shared, np.concatenate(own), np.concatenate(onsets)]


def fit_joint_chain(
    pulses: Sequence[ImpactPulses | None], start: dict[str, float]
) -> SensorChain | None:
    """The sensor chain of a campaign, fitted once to the impacts of all its recordings.

    Parameters
    ----------
    pulses : sequence of ImpactPulses or None
        Each recording's impacts (:func:`impact_pulses`; None: unread, left out).
    start : dict
        The pooled chain as a data sheet (``resonance_hz``, ``resonance_damping``,
        ``lowpass_hz``, ``lowpass_order``, ``highpass_hz``): its stages are the ones fitted,
        from its values; a low-pass is fitted at each order of
        :data:`~stiffnet.restoring_force.chain.ORDERS` (the structures have as many
        parameters, so the least squared residual picks the order).

    Returns
    -------
    SensorChain or None
        The joint chain (``source`` ``"fitted"``; intervals at
        :data:`~stiffnet.restoring_force.chain.COVERAGE` from the joint Jacobian; the
        high-pass is the start's), or None with fewer than 2 recordings' impacts or no
        resonance or low-pass to fit.
    """
    pulses = [p for p in pulses if p is not None]
    fs_low = min((p.fs_hz for p in pulses), default=0.0)
    res = bool(start.get("resonance_hz")) and start["resonance_hz"] < 0.49 * fs_low
    corner = start.get("lowpass_hz") if (start.get("lowpass_hz") or 0) < 0.49 * fs_low else None
    if len(pulses) < 2 or not (res or corner):
        return None
    shared_res = [np.log(start["resonance_hz"]), np.log(start.get("resonance_damping") or 0.05)]
    shared_res = shared_res if res else []
    best = None
    for order in ORDERS if corner else (0,):
        problem = _JointProblem(pulses, (res, order))
        starts = []
        for f in CORNER_STARTS if corner else (1.0,):
            shared = np.array(shared_res + ([np.log(f * corner)] if corner else []))
            shared = np.clip(shared, problem.lower[: problem.ns] + 1e-6,
                             problem.upper[: problem.ns] - 1e-6)  # fmt: skip
            starts.append(shared)
        # each recording's contact fitted once, behind the pooled corner; the other corner
        # starts share it (the contact moves little with a corner change of 25 %)
        first = _start(problem, starts[len(starts) // 2])
        thetas = [np.r_[s, first[problem.ns :]] for s in starts]
        x, sse, jac = problem.solve(thetas)
        if best is None or sse < best[2]:
            best = (problem, x, sse, jac)
    problem, x, sse, jac = best
    return _joint_chain(problem, x, sse, jac, float(start.get("highpass_hz") or 0.0))


def _joint_chain(problem: _JointProblem, x, sse: float, jac, highpass_hz: float) -> SensorChain:
    """The fitted chain with its intervals (the shared parameters' block of the covariance)."""
    res, order = problem.structure
    shared = x[: problem.ns]
    jac = jac.toarray() if hasattr(jac, "toarray") else np.asarray(jac)
    m, p = jac.shape[0], jac.shape[1] + 3 * sum(problem.counts)  # + each impact's size, baseline
    cov = np.linalg.pinv(jac.T @ jac)[: problem.ns, : problem.ns] * sse / max(m - p, 1)
    z = float(stats.norm.ppf(0.5 + COVERAGE / 2))
    names = (["resonance_hz", "resonance_damping"] if res else []) + (
        ["lowpass_hz"] if order else []
    )
    intervals = {}
    for i, name in enumerate(names):
        se = float(np.sqrt(max(cov[i, i], 0.0)))
        with np.errstate(over="ignore"):
            ends = [float(np.exp(shared[i] - z * se)), float(np.exp(shared[i] + z * se))]
        if all(np.isfinite(ends)):
            intervals[name] = ends
    k = 2 if res else 0
    return SensorChain(
        resonance_hz=float(np.exp(shared[0])) if res else None,
        resonance_damping=float(np.exp(shared[1])) if res else None,
        lowpass_hz=float(np.exp(shared[k])) if order else None,
        lowpass_order=int(order) if order else None,
        highpass_hz=highpass_hz,
        source="fitted",
        intervals=intervals,
    )
