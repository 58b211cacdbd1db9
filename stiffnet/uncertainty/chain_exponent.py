"""What exponent a training-world contact law reads through a sensor chain's low-pass.

A low-pass delays and rounds each contact pulse, and the restoring-force map it leaves bends
a linear law as a stiffening exponent does. Whether a map's exponent is a law the training
world lacks or that world's own law seen through a chain the record cannot exclude is a
forward question: pass the pulses of a linear (and a Hertz) contact of the record's own
contact duration through that low-pass, and read them with the restoring-force estimate's
own exponent fit (:func:`stiffnet.restoring_force.contact_law.fit_contact_law`, the chain's
sections from :func:`stiffnet.restoring_force.chain.chain_sos`). Time is counted in samples,
so the reading depends only on the contact's duration in samples and on the corner over the
sampling rate.

The pulses are a bouncing mass's: a constant pull between impacts (the outer spring is slow
against a contact) and a contact of ``samples_per_contact`` samples, the impacts placed at
sub-sample phases that differ from one to the next as a record's do.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

#: Impacts of the forward record (enough for the median peak penetration and the fit).
FORWARD_IMPACTS = 12
#: Free flight between impacts, in contact durations: long enough for the slowest prior
#: low-pass (order 4 at 0.05 of the sampling rate) to settle between pulses.
FORWARD_FLIGHT_RATIO = 5.0
#: The training priors' lowest low-pass corner over the sampling rate and their highest order
#: (``configs/sim/default.yaml``, ``sensor_dynamics``): what a record whose cross-check undid
#: no chain does not exclude.
PRIOR_LOWPASS_OVER_FS = 0.05
PRIOR_LOWPASS_ORDER = 4


def _contact_shape(exponent: float, n: int) -> np.ndarray:
    """Penetration over one contact of a law ``delta'' = -delta^p``, normalised to a unit
    duration and a unit peak, on ``n`` points from touch to release."""
    if exponent == 1.0:
        return np.sin(np.pi * np.linspace(0.0, 1.0, n))
    # symmetric: integrate the loading half from the peak (delta = 1, v = 0) down to touch
    dt, d, v, ds = 1e-4, 1.0, 0.0, [1.0]
    while d > 0.0:
        for _ in range(2):  # semi-implicit Euler, fine enough at this step
            v -= max(d, 0.0) ** exponent * dt
            d += v * dt
        ds.append(max(d, 0.0))
    half = np.asarray(ds[::-1])
    full = np.concatenate([half, half[-2::-1]])
    return np.interp(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, full.size), full)


def forward_record(
    exponent: float, samples_per_contact: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampled penetration, contact force and in-contact mask of :data:`FORWARD_IMPACTS`
    impacts of a law of `exponent` lasting `samples_per_contact` samples (unit sampling rate,
    unit peak penetration)."""
    tc = float(samples_per_contact)
    tf = FORWARD_FLIGHT_RATIO * tc
    shape = _contact_shape(float(exponent), 2001)
    # the touch speed that makes the free flight's pull return the mass in tf: the contact's
    # velocity at touch, in the contact's unit (peak 1, duration tc)
    v0 = float(np.gradient(shape, 1.0 / (shape.size - 1))[0]) / tc
    rng = np.random.default_rng(0)
    starts = np.cumsum(np.full(FORWARD_IMPACTS, tc + tf)) + rng.uniform(0, 1, FORWARD_IMPACTS)
    n = int(np.ceil(starts[-1] + tc + tf))
    t = np.arange(n, dtype=float)
    x = np.full(n, np.nan)
    prev_end = 0.0
    for s in starts:
        inside = (t >= s) & (t <= s + tc)
        x[inside] = np.interp((t[inside] - s) / tc, np.linspace(0, 1, shape.size), shape)
        flight = (t >= prev_end) & (t < s)
        tau = t[flight] - (s - tf)
        x[flight] = -v0 * tau + (v0 / tf) * tau**2  # leaves at -v0, returns at +v0
        prev_end = s + tc
    tail = t > prev_end
    x[tail] = -v0 * (t[tail] - prev_end) + (v0 / tf) * (t[tail] - prev_end) ** 2
    first = np.isnan(x)
    x[first] = 0.0
    contact = x > 0.0
    force = np.where(contact, np.clip(x, 0.0, None) ** float(exponent), 0.0)
    return x, force, contact


@lru_cache(maxsize=1024)
def exponent_through_lowpass(
    exponent: float, samples_per_contact: float, lowpass_over_fs: float, order: int
) -> float | None:
    """The exponent the estimate's fit reads on a law of `exponent` through a Butterworth
    low-pass of `order` at `lowpass_over_fs` of the sampling rate, on contacts of
    `samples_per_contact` samples; None where the fit has nothing to read.

    The force and the penetration both pass the chain (the map's displacement is the
    chain's output integrated twice), and the estimate's exponent fit
    (:func:`~stiffnet.restoring_force.contact_law.fit_contact_law`, the exponent free within
    its bounds) reads them on the samples near the impacts, as the estimate does.

    Examples
    --------
    >>> round(exponent_through_lowpass(1.0, 40.0, 0.45, 2), 1)
    1.0
    """
    from scipy import signal

    from stiffnet.restoring_force.chain import SensorChain, chain_sos
    from stiffnet.restoring_force.contact_law import fit_contact_law, linear_contact_start
    from stiffnet.restoring_force.estimate import impact_regions

    if not samples_per_contact >= 3 or not 0.0 < lowpass_over_fs < 0.5:
        return None
    x, force, contact = forward_record(exponent, samples_per_contact)
    sos = chain_sos(SensorChain(lowpass_hz=lowpass_over_fs, lowpass_order=int(order)), 1.0)
    if sos is not None:
        x, force = signal.sosfilt(sos, x), signal.sosfilt(sos, force)
    vel = np.gradient(x)
    # the map's contact is where its force stands out, as the estimate's is
    core = force > 0.05 * float(np.max(force))
    labels, n_imp = impact_regions(core, max(2, int(0.3 * samples_per_contact)))
    if n_imp < 3:
        return None
    near = labels > 0
    kc0, e0, cc0 = linear_contact_start(force, x, vel, core)
    if not np.isfinite(kc0):
        return None
    peaks = [float(np.max(x[labels == i] - e0)) for i in range(1, n_imp + 1)]
    dr = float(np.median(peaks))
    if not dr > 0:
        return None
    law = fit_contact_law(force, x, vel, near, (kc0, e0, cc0), dr, 1.0)
    free = fit_contact_law(force, x, vel, near, (law.stiffness, law.onset, law.damping), dr)
    return float(free.exponent)


def unexcluded_lowpass(
    restoring_force: dict[str, Any],
    prior_over_fs: float = PRIOR_LOWPASS_OVER_FS,
    prior_order: int = PRIOR_LOWPASS_ORDER,
) -> tuple[float, int, str] | None:
    """The lowest low-pass the record does not exclude, as ``(corner over the sampling rate,
    order, what it is)``; None where nothing places it.

    Where the cross-check identified a chain and undid it, the lowest of the low-passes its
    impacts fit as well (``sensor.lowpass_not_excluded``; the sampling rate from the fitted
    contact frequency and the contacts' duration in samples: ``fs = 2 f_c spc /
    duration_ratio``), None where it excluded them all. Elsewhere the record excludes none of
    the training priors' low-passes: the prior's lowest corner at its highest order
    (`prior_over_fs`, `prior_order`).
    """
    sensor = restoring_force.get("sensor") or {}
    if not sensor.get("applied"):
        return prior_over_fs, int(prior_order), "the training priors' lowest low-pass"
    left = [
        (float(lp["hz"]), int(lp["order"]))
        for lp in sensor.get("lowpass_not_excluded") or []
        if lp.get("hz") is not None and lp.get("order") is not None
    ]
    spc, ratio = restoring_force.get("samples_per_contact"), restoring_force.get("duration_ratio")
    contact_hz = sensor.get("contact_hz")
    if not left or not contact_hz or not spc or not ratio or not ratio > 0:
        return None
    fs = 2.0 * float(contact_hz) * float(spc) / float(ratio)
    hz, order = min(left)
    return hz / fs, order, "the lowest low-pass the undone chain's impacts do not exclude"


def exponents_through_lowpass(
    samples_per_contact: float, lowpass_over_fs: float, order: int
) -> tuple[float, float] | None:
    """What a linear and a Hertz contact read (:func:`exponent_through_lowpass`) through the
    low-pass, on contacts the record's duration long, read through it."""
    spc = round(float(samples_per_contact), 1)  # the cache's key: a tenth of a sample
    corner = round(float(lowpass_over_fs), 4)
    linear = exponent_through_lowpass(1.0, spc, corner, int(order))
    hertz = exponent_through_lowpass(1.5, spc, corner, int(order))
    if linear is None or hertz is None:
        return None
    return linear, hertz
