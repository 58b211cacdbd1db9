"""Beta of contacts too soft to stand out of the free-flight law: free flight and contact
fitted jointly.

**Why.** The map (:mod:`.free_flight`) splits the contacts off as outliers of the
free-flight law ``-y = c v + k x`` with the table's motion at the forcing harmonics
:data:`~.free_flight.HARMONICS`. A soft contact lasts a large share of the forcing period
(beta 5.8 at ``f_f ~ f_n``: a half period ``pi / (omega_n sqrt(1 + beta))`` of about 0.2
forcing periods, longer where the forcing holds the mass against the stop); the table's
harmonics 1-3 and the damping absorb most of its force, the scatter of the rest is as large
as its peak, and no sample stands out (:func:`~.band.smoothed_contact_refusal` then sees its
harmonics 4 and beyond). The force is there; only the split fails.

**The model.** The paper's eqs 11-12 in non-dimensional time ``t`` (forcing radians here,
``k = (f_n / f_f)^2``), ``v' = a w^2 sin(w t) - 2 xi v - x - beta (x - e) H(x - e)``, read
as the map does (:mod:`.free_flight`: the accelerometer's ``y`` is the mass's absolute
acceleration, the table's motion enters at the forcing harmonics), with a Kelvin-Voigt
contact that releases at zero force, in the record's gain::

    -y = c v + k x + sum_m (p_m cos m tau + q_m sin m tau) + d
         + [K (x - e) + c_c v]  where x > e and K (x - e) + c_c v > 0

``x = x_i + s + x_0`` is the relative displacement (``x_i`` the integrated record, ``s``
the table's displacement from ``p_m, q_m`` and ``x_0 = d / k``, as in
:func:`~.free_flight.fit_free_flight`), and ``beta = K / k``. For a given onset ``e``, free
damping ``c`` and contact set the model is linear in ``d, p_m, q_m, K, c_c``: the onset is
profiled (a grid of the displacement's upper quantiles, then a bounded search), the
contact set is the samples beyond it whose force is compressive, and ``s`` is updated from
the fitted ``p_m, q_m`` (:data:`TABLE_UPDATES`; its first pass is the free-flight fit's,
which the contact's force biased). The free damping is profiled over
:data:`FREE_DAMPING_RATIOS`: near resonance ``c v`` and the table's first harmonic trade
freely, and a free ``c`` ran off to damping ratios of 0.6-3 as ``s`` was updated.

**Interval.** Bootstrap over forcing periods (each period's normal equations at the fitted
onset, damping and contact set, resampled with replacement; the percentile interval), the
readings at the neighbouring free damping ratios whose fit is as good (within
:data:`DAMPING_SSE_SLACK` of the best sum of squares), and in quadrature this fit's own
systematic floor (:data:`SYSTEMATIC`) with the misfit and samples-per-contact terms of
:func:`~.estimate.widen_interval`.

**Why not the pulse's spectrum.** The excess harmonics carry the pulses' spectrum, and a
half-sine of duration ``pi / omega_c`` has nulls at odd multiples of ``omega_c``; but a soft
contact's pulse is an arc of the contact's oscillation about a centre the gap and the
forcing shift (``-e / (1 + beta)`` in eq. 12's units, beyond the onset on the free side), so
a shallow contact lasts much less than that half period and its duration does not give
beta. The joint fit reads the law from the state, as the map does.

**Through a known chain.** The model's acceleration meets the record through the chain's
response (forward: :func:`through_chain`), its state from the record with the chain divided
out (:func:`motion_of_record`). A lightly damped mount rings after every contact; fitted to
the record as recorded, the joint law leaves that ring unexplained and describes no contacts
(stiffnet's engine, beta 7.6 behind a mount at 15 f_n, zeta 0.011, and a 3rd-order low-pass
at 18 f_n, the chain given: refused; through it 7.33 [6.72, 7.99], docs/crosscheck.md).

**When it is read.** Only where the band is known to carry every contact (the caller's
rule: a known chain whose low-pass passes every contact up to the classes' top, or none),
or, with no chain known, where the fit itself leaves none of the record's harmonics beyond
its noise (:func:`~.band.chain_free_reading`): a low-pass below the contact rounds the pulse
into a shape a linear contact fits with the wrong stiffness, and leaves the harmonics. And
only where the fit describes contacts: at least :data:`MIN_CONTACTS` contact runs,
compressive, the contact explaining at least
:data:`MIN_SHARE` of what the free-flight law leaves, and contacts lasting no longer than
the fitted law allows.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize, signal

from stiffnet.restoring_force.chain import MAX_GAIN, SensorChain, chain_sos
from stiffnet.restoring_force.free_flight import (
    HARMONICS,
    free_flight_design,
    scaled_lstsq,
    table_motion,
)
from stiffnet.restoring_force.reconstruct import ALIAS_MIN_DAMPING, integrate_spectral

#: Free-flight damping ratios profiled (from none to twice the priors' 0.01-0.05).
FREE_DAMPING_RATIOS = (0.0, 0.015, 0.03, 0.05, 0.08)
#: Onsets profiled: this many quantiles of the relative displacement ...
ONSET_GRID = 24
#: ... refined by a bounded search to this share of the displacement's range, ...
ONSET_TOLERANCE = 1e-4
#: ... between these (a soft contact can hold the mass beyond the onset for a third of
#: the period; the top half-percent is the deepest penetration).
ONSET_QUANTILES = (0.3, 0.995)
#: Updates of the table's motion (its first pass comes from the free-flight fit, which the
#: contact's force biased) and of the contact set at each onset (release at zero force).
TABLE_UPDATES = 8
RELEASE_UPDATES = 2
#: Readings at other free damping ratios whose sum of squares is within this share of the
#: best join the interval (what the record cannot tell apart).
DAMPING_SSE_SLACK = 0.05
#: Contacts needed (runs of contact samples) ...
MIN_CONTACTS = 3
#: ... and the share of the free-flight law's residual sum of squares the contact must explain.
MIN_SHARE = 0.5
#: ... and contacts lasting at most this many half periods of the fitted law (the map's
#: own rule, :data:`~.estimate.MAX_DURATION_RATIO`).
MAX_DURATION_RATIO = 2.0
#: Systematic half-width (log beta) of the joint fit, in quadrature with the map's terms:
#: the free damping read on a grid and the contact set sampled bias the reading by up to
#: 4.7 % on the independent rig's soft contacts (beta 5-10, damped and not, 0-3 % noise;
#: set on those simulations, docs/crosscheck.md), more than the map's 2 % floor.
SYSTEMATIC = 0.05
#: Bootstrap replicates over forcing periods.
N_BOOTSTRAP = 200

#: Columns of the joint design: the free-flight law's constant and table harmonics, then
#: the contact's stiffness and damping.
_FREE_COLUMNS = 1 + 2 * len(HARMONICS)
_K, _CC = _FREE_COLUMNS, _FREE_COLUMNS + 1


@dataclass(frozen=True)
class SoftContactFit:
    """The joint fit of :func:`fit_soft_contact`.

    Attributes
    ----------
    beta : float
        ``K / k``.
    interval : tuple of float
        Bootstrap interval over forcing periods with the neighbouring damping readings,
        widened by the systematic terms (:data:`SYSTEMATIC`).
    contact_damping_ratio : float
        ``c_c / (2 sqrt(K))``.
    free_damping_ratio : float
        The profiled ``c / (2 sqrt(k))``.
    share : float
        Share of the free-flight law's residual sum of squares the contact explains.
    n_contacts : int
        Runs of contact samples within the used samples.
    samples_per_contact : float
        Median samples per contact run.
    duration_ratio : float
        Median contact duration over the law's half period ``pi / sqrt(K + k)``.
    displacement, velocity, force : numpy.ndarray
        The relative state and the force beyond the free-flight law, for the figure.
    residual : numpy.ndarray
        What the joint law leaves of the record, on the used samples (the record's units):
        white at the record's noise where free flight and contact are the whole record, the
        forcing's harmonics where a sensor chain shaped the pulses
        (:func:`~.band.chain_free_reading`).
    """

    beta: float
    interval: tuple[float, float]
    contact_damping_ratio: float
    free_damping_ratio: float
    share: float
    n_contacts: int
    samples_per_contact: float
    duration_ratio: float
    displacement: np.ndarray
    velocity: np.ndarray
    force: np.ndarray
    residual: np.ndarray


@dataclass
class _Pass:
    """One joint fit at a free damping ratio."""

    sse: float
    coef: np.ndarray
    design: np.ndarray
    target: np.ndarray
    x: np.ndarray
    v: np.ndarray
    inside: np.ndarray


def _relative_state(coef, disp_i, vel_i, tau, k, c) -> tuple[np.ndarray, np.ndarray]:
    """``x = x_i + s + x_0`` and ``v = v_i + s'`` from the fitted table harmonics."""
    table = table_motion(coef[1:_FREE_COLUMNS], k, c)
    x, v = disp_i + coef[0] / k, vel_i.copy()
    for (ca, sa), m in zip(table, HARMONICS, strict=True):
        x = x + ca * np.cos(m * tau) + sa * np.sin(m * tau)
        v = v + m * (sa * np.cos(m * tau) - ca * np.sin(m * tau))
    return x, v


def through_chain(columns: np.ndarray, response: np.ndarray | None) -> np.ndarray:
    """`columns` (samples along axis 0) through a chain's response per ``rfft`` bin, applied
    as a periodic filter (the record spans whole forcing periods); unchanged without one."""
    if response is None:
        return columns
    spec = np.fft.rfft(columns, axis=0)
    shape = (-1,) + (1,) * (columns.ndim - 1)
    return np.fft.irfft(spec * response.reshape(shape), columns.shape[0], axis=0)


def motion_of_record(y: np.ndarray, response: np.ndarray | None) -> np.ndarray:
    """The acceleration whose integrals give the state: the record with the chain divided
    out (the gain capped at :data:`~.chain.MAX_GAIN`), the record itself without a chain.

    The model meets the record through the chain, but its state must be the mass's own: the
    chain's high-pass turns the forcing's phase by ``atan(f_h / f_f)`` and lowers its
    amplitude, and a resonance's ring integrates into the velocity, so that the state of the
    record as recorded puts the onset and the contact's damping in the wrong place (true
    chain forward without the state undone: beta 21.8 read 3.6, 7.6 read 2.1). What the
    division amplifies above the low-pass is noise divided by ``w`` and ``w^2``.
    """
    if response is None:
        return y
    mag = np.abs(response)
    h = np.where(mag * MAX_GAIN < 1.0, np.exp(1j * np.angle(response)) / MAX_GAIN, response)
    return np.fft.irfft(np.fft.rfft(y) / h, y.size)


def _contact_columns(inside, pen, v, response) -> np.ndarray:
    """The contact's stiffness and damping columns, through the chain where one is given."""
    return through_chain(np.column_stack([np.where(inside, pen, 0.0), np.where(inside, v, 0.0)]),
                         response)  # fmt: skip


def _at_onset(free: np.ndarray, target, x, v, e: float, use, response=None) -> tuple:
    """Least squares at one onset: the contact set released where the force turns tensile."""
    pen = x - e
    inside = pen > 0
    for _ in range(RELEASE_UPDATES + 1):
        design = np.column_stack([free, _contact_columns(inside, pen, v, response)])
        coef = scaled_lstsq(design[use], target[use])
        inside = (pen > 0) & (coef[_K] * pen + coef[_CC] * v > 0)
    design = np.column_stack([free, _contact_columns(inside, pen, v, response)])
    coef = scaled_lstsq(design[use], target[use])
    r = target[use] - design[use] @ coef
    return float(r @ r), coef, design, inside


def _onset_cost(free, target, x, v, use, response, e: float) -> float:
    """The joint fit's sum of squares at onset `e` (:func:`_at_onset`)."""
    return _at_onset(free, target, x, v, float(e), use, response)[0]


def _joint_pass(y, disp_i, vel_i, tau, use, k, ratio, x_start, response=None) -> _Pass:
    """The joint fit at one free damping ratio: onset profiled, the table updated; the
    model's acceleration through the chain's `response` where one is given."""
    c = 2.0 * ratio * np.sqrt(k)
    free = through_chain(free_flight_design(vel_i, disp_i, tau)[:, 2:], response)
    # term by term: through no chain, the same sums as the chain-free fit's, to the bit
    target = -y - through_chain(k * disp_i, response) - through_chain(c * vel_i, response)
    x, v = x_start, vel_i
    best = None
    for _ in range(TABLE_UPDATES):
        onsets = np.quantile(x[use], np.linspace(*ONSET_QUANTILES, ONSET_GRID))
        cost = functools.partial(_onset_cost, free, target, x, v, use, response)
        sses = [cost(float(e)) for e in onsets]
        i = int(np.argmin(sses))
        sol = optimize.minimize_scalar(
            cost,
            bounds=(onsets[max(i - 1, 0)], onsets[min(i + 1, onsets.size - 1)]),
            method="bounded",
            options={"xatol": ONSET_TOLERANCE * float(np.ptp(x[use]))},
        )
        e = float(sol.x) if sol.fun < sses[i] else float(onsets[i])
        sse, coef, design, inside = _at_onset(free, target, x, v, e, use, response)
        best = _Pass(sse, coef, design, target, x, v, inside)
        if not coef[_K] > 0:
            break
        x, v = _relative_state(coef, disp_i, vel_i, tau, k, c)
    return best


def _period_bootstrap(p: _Pass, use, period: float, k: float, coverage, rng) -> tuple:
    """Percentile interval of ``K / k`` over forcing periods resampled with replacement, the
    onset, damping and contact set held (each period's normal equations summed)."""
    idx = np.flatnonzero(use)
    which = (idx // period).astype(int)
    periods = np.unique(which)
    a, t = p.design[idx], p.target[idx]
    norms = np.sqrt(np.einsum("ij,ij->j", a, a))
    norms[norms == 0] = 1.0
    a = a / norms
    gram = np.stack([a[which == j].T @ a[which == j] for j in periods])
    rhs = np.stack([a[which == j].T @ t[which == j] for j in periods])
    counts = rng.multinomial(periods.size, np.full(periods.size, 1.0 / periods.size), N_BOOTSTRAP)
    ridge = 1e-12 * np.eye(a.shape[1])
    betas = []
    for w in counts:
        coef = np.linalg.lstsq(np.tensordot(w, gram, 1) + ridge, w @ rhs, rcond=None)[0]
        betas.append(coef[_K] / norms[_K] / k)
    alpha = 0.5 * (1.0 - coverage)
    lo, hi = np.quantile(betas, [alpha, 1.0 - alpha])
    return float(lo), float(hi)


def _damping_passes(y, dtau, tau, use, k, start, response, lines_only: bool) -> dict:
    """The joint fit at each free damping ratio (:data:`FREE_DAMPING_RATIOS`), the state
    integrated from the record (`lines_only`: from its forcing lines alone,
    :func:`~.reconstruct.integrate_spectral`)."""
    vel_i, disp_i = integrate_spectral(motion_of_record(y, response), dtau,
                                       forcing_lines_only=lines_only)  # fmt: skip
    return {r: _joint_pass(y, disp_i, vel_i, tau, use, k, r, start, response)
            for r in FREE_DAMPING_RATIOS}  # fmt: skip


def _damping_ratio(p: _Pass) -> float:
    """The contact damping ratio ``c_c / (2 sqrt(K))`` of a pass (nan where ``K <= 0``)."""
    stiff = float(p.coef[_K])
    return float(p.coef[_CC]) / (2.0 * np.sqrt(stiff)) if stiff > 0 else float("nan")


def fit_soft_contact(
    y: np.ndarray,
    dtau: float,
    tau: np.ndarray,
    use: np.ndarray,
    period: float,
    stiffness: float,
    start_displacement: np.ndarray,
    coverage: float = 0.9,
    seed: int = 0,
    response: np.ndarray | None = None,
) -> SoftContactFit | None:
    """Rule: beta of contacts that do not stand out, by the joint fit of the module notes;
    None where the fit describes no contacts.

    Parameters
    ----------
    y : numpy.ndarray
        The record as the map reads it (polarity: contact forces push ``-y`` up; the
        high-pass and any known chain undone), whole forcing periods.
    dtau : float
        Sampling step, forcing radians.
    tau, use : numpy.ndarray
        Sample times (forcing radians) and the samples the fit may use.
    period : float
        Samples per forcing period.
    stiffness : float
        ``k = (f_n / f_f)^2``, known.
    start_displacement : numpy.ndarray
        The free-flight fit's relative displacement: the first contact set's.
    coverage : float
        Nominal coverage of the bootstrap interval.
    seed : int
        Seed of the bootstrap.
    response : numpy.ndarray, optional
        A sensor chain's complex response per ``rfft`` bin of `y`: the model's acceleration
        is passed through it (forward) before it meets `y` as recorded, and the state is
        integrated from `y` with the chain divided out (:func:`motion_of_record`).

    Returns
    -------
    SoftContactFit or None
    """
    k = stiffness
    passes = _damping_passes(y, dtau, tau, use, k, start_displacement, response, False)
    ratio = min(passes, key=lambda r: passes[r].sse)
    recorded = []  # the reading of the record as integrated, where the other is kept
    if _damping_ratio(passes[ratio]) >= ALIAS_MIN_DAMPING:
        # a damped contact's step may have aliased between the forcing lines: the state
        # integrated from them alone is kept where the joint law then fits better, and the
        # interval reaches the record's own reading (the fit does not prove which lines are
        # the mass's)
        lines = _damping_passes(y, dtau, tau, use, k, start_displacement, response, True)
        best = min(lines, key=lambda r: lines[r].sse)
        if lines[best].sse < passes[ratio].sse:
            recorded = [float(passes[ratio].coef[_K]) / k] if passes[ratio].coef[_K] > 0 else []
            passes, ratio = lines, best
    p = passes[ratio]
    stiff = float(p.coef[_K])
    if not stiff > 0:
        return None
    labels, n = ndimage.label(p.inside & use)
    spc = float(np.median(np.bincount(labels.ravel())[1:])) if n else 0.0
    free_only = scaled_lstsq(p.design[use][:, :_FREE_COLUMNS], p.target[use])
    r0 = p.target[use] - p.design[use][:, :_FREE_COLUMNS] @ free_only
    share = 1.0 - p.sse / max(float(r0 @ r0), 1e-300)
    duration = spc * dtau / (np.pi / np.sqrt(stiff + k))
    if n < MIN_CONTACTS or share < MIN_SHARE or duration > MAX_DURATION_RATIO:
        return None
    beta = stiff / k
    lo, hi = _period_bootstrap(p, use, period, k, coverage, np.random.default_rng(seed))
    others = [
        float(passes[r].coef[_K]) / k
        for r in FREE_DAMPING_RATIOS
        if r != ratio and passes[r].sse <= (1.0 + DAMPING_SSE_SLACK) * p.sse
    ]
    lo, hi = min(lo, beta, *others, *recorded), max(hi, beta, *others, *recorded)
    # the reconstruction's systematic terms (:func:`~.estimate.widen_interval`'s misfit and
    # samples-per-contact terms) with this fit's own floor, in quadrature; imported here, as
    # the estimate imports this module
    from stiffnet.restoring_force.estimate import SYSTEMATIC_PER_MISFIT

    sys_hw = float(np.linalg.norm([SYSTEMATIC, SYSTEMATIC_PER_MISFIT * (1.0 - share), 1.0 / spc]))
    lo = beta * np.exp(-np.hypot(np.log(beta / lo), sys_hw)) if lo > 0 else 0.0
    hi = beta * np.exp(np.hypot(np.log(hi / beta), sys_hw))
    force = p.target - p.design[:, :_FREE_COLUMNS] @ p.coef[:_FREE_COLUMNS]
    return SoftContactFit(
        beta=beta,
        interval=(float(lo), float(hi)),
        contact_damping_ratio=_damping_ratio(p),
        free_damping_ratio=float(ratio),
        share=float(share),
        n_contacts=int(n),
        samples_per_contact=spc,
        duration_ratio=float(duration),
        displacement=p.x[use],
        velocity=p.v[use],
        force=force[use],
        residual=(p.target - p.design @ p.coef)[use],
    )


def record_response(chain: SensorChain, fs_hz: float, n: int) -> np.ndarray:
    """The chain's response per ``rfft`` bin of an `n`-sample record: its digital
    resonance and low-pass (:func:`~.chain.chain_sos`, as a logger's sections) and its
    first-order high-pass."""
    f = np.fft.rfftfreq(n, 1.0 / fs_hz)
    sos = chain_sos(chain, fs_hz)
    h = np.ones(f.size, complex) if sos is None else signal.sosfreqz(sos, worN=f, fs=fs_hz)[1]
    if chain.highpass_hz:
        h = h * (1j * f) / (1j * f + chain.highpass_hz)
    return h
