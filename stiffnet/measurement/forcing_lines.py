"""The shaker's harmonics read off the free flights: levels and phases in closed form.

Between impacts the oscillator is linear (eq. 12 with ``H = 0``), and the
accelerometer reads ``y = x'' - F`` with ``x`` the displacement relative to the
table and ``F`` the forcing (:mod:`stiffnet.restoring_force.reconstruct`).
Integrating the record twice gives ``x`` up to sinusoids ``s`` at the forcing
harmonics with ``s'' = F``, so with the row's stiffness ``k = (f_n / f_f)**2``
and damping ``c = 2 zeta sqrt(k)`` known, the free-flight law is a regression
*linear* in the forcing's lines (:mod:`stiffnet.restoring_force.free_flight`)::

    -y - k x_i - c v_i = sum_m (p_m cos m tau + q_m sin m tau) + d

The impacts are one-sided outliers of it (split off by
:func:`~stiffnet.restoring_force.free_flight.robust_split`). Each line of the
forcing follows from ``(p_m, q_m)`` through the oscillator's transfer
(:func:`~stiffnet.restoring_force.free_flight.table_motion`, ``F_m = -m**2 s_m``).
Written ``F_m = R_m sin(m tau + psi_m)``, the harmonics of
:class:`~stiffnet.effects.forcing_harmonics.ForcingHarmonics`
(``sin(m w t + phi_m)`` beside ``sin w t``) are ``h_m = R_m / R_1`` and
``phi_m = psi_m - m psi_1``: the record's unknown start time drops out.

This is the global stage of the harmonics' fit. Their phases make the
campaign discrepancy multimodal (the orbit moves with them), whereas the
regression has one answer per recording; the campaign's reading is the median
of the recordings' ``h_m exp(i phi_m)``, with its standard error from their
scatter. The fit starts at the reading and searches only its confidence region
(:meth:`ForcingHarmonics.fit_seeds`, :meth:`ForcingHarmonics.observed_fit_space`):
the simulated statistics resolve the harmonics less finely than the reading does
(an orbit jump, the noise floor). A sensor mounted the other way would turn
``phi_2`` by pi, so the record is first turned to the simulator's polarity (the
spikes point down). Nothing here simulates: a few least-squares solves per recording.

Behind a sensor chain the free flight is not the law above alone: the record is the
motion through the chain, and each contact pulse leaves the chain's free response after
it, sum of its modes. A mount (210 Hz, zeta 0.05) rings on for its decay time, 15 ms of a
100 ms period, lobes of both signs; the split cuts the lobes above its threshold and
keeps the rest, once per period, so they read as forcing lines: campaign a of the held-out
check (a damped contact behind that mount and a 320 Hz 4th-order low-pass) read 0.361 /
0.315 for harmonics of 0.06 / 0.025, and the same campaign without harmonics 0.402 / 0.317;
without the chain 0.061 / 0.027. With the campaign's identified chain the regression
carries the chain's free modes after each impact (:func:`free_mode_columns`), two
regressors per mode and impact, linear like the rest, and the split is redone with them
until the contact stands; the lines are then divided by the chain's response at each
harmonic (a few per cent at most). Through its identified chain campaign a then reads
0.0605 at 0.92 rad and 0.0305 at -1.24 rad (truth 0.06 at 0.9, 0.025 at -1.3), and
without harmonics 0.001 / 0.005.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy import ndimage, signal

from stiffnet.campaign import ManifestRow
from stiffnet.campaign.simulate import natural_frequency
from stiffnet.measurement.nuisance import DEFAULT_DAMPING  # a row that names none
from stiffnet.restoring_force.chain import (
    SensorChain,
    chain_response,
    sensor_from_mapping,
    shared_chain_sheet,
)
from stiffnet.restoring_force.free_flight import robust_split, table_motion
from stiffnet.restoring_force.reconstruct import integrate_spectral, periodic_length

#: Forcing lines read (1 = the fundamental; the shaker's 2nd and 3rd).
ORDERS = (1, 2, 3)
#: Whole forcing periods a record must hold to be read (the integration needs several).
MIN_PERIODS = 4
#: A recording's reading is kept when its fundamental carries at least this share of the
#: free-flight target's spread (otherwise the flights are too short or too noisy to say).
MIN_FUNDAMENTAL = 0.2
#: Contact runs closer than this many decay times of the chain's slowest mode are one
#: impact: the lobes of a mount's ringing that rise above the split's cut follow the
#: contact at the mount's period.
IMPACT_JOIN_DECAYS = 1.0
#: Splits redone with the chain's free modes at most (it stops once the contact stands: the
#: first pass with the modes frees the lobes, measured 42 % of the samples in contact -> 15 %).
RINGING_PASSES = 3
#: Behind a chain, a record is read in windows of at most this many forcing periods: each
#: impact brings its own regressors, and the dense design would grow with the square of
#: the record's length.
WINDOW_PERIODS = 40


def spikes_polarity(accel: np.ndarray) -> int:
    """-1 where the record's extreme excursions (the contact spikes) point down (the
    simulator's polarity: contact forces push ``-accel`` up), else +1."""
    med = float(np.median(accel))
    lo, hi = np.percentile(accel, [0.5, 99.5])
    return -1 if med - lo >= hi - med else 1


def chain_modes(chain: SensorChain) -> tuple[list[complex], list[complex]]:
    """The chain's free modes as analog poles in the upper half plane (rad/s): the mount's
    (it rings on through the flight) and the low-pass's (it dies a few samples after the
    pulse)."""
    mount = []
    if chain.resonance_hz:
        w, z = 2 * np.pi * chain.resonance_hz, float(chain.resonance_damping or 0.0)
        mount.append(complex(-z * w, w * math.sqrt(max(1.0 - z * z, 0.0))))
    lowpass = []
    if chain.lowpass_hz:
        poles = signal.buttap(int(chain.lowpass_order or 2))[1] * 2 * np.pi * chain.lowpass_hz
        lowpass = [complex(p) for p in poles if p.imag >= 0]
    return mount, lowpass


def _mode_block(n: int, start: int, stop: int, fs_hz: float, poles: list[complex]) -> list:
    """Columns ``exp(p t)`` (real and imaginary parts) on samples ``start:stop``, ``t`` from
    `start`, zero elsewhere."""
    t = np.arange(stop - start) / fs_hz
    cols = []
    for p in poles:
        e = np.exp(p * t)
        for part in (e.real, e.imag) if p.imag > 0 else (e.real,):
            col = np.zeros(n)
            col[start:stop] = part
            cols.append(col)
    return cols


def free_mode_columns(contact: np.ndarray, fs_hz: float, chain: SensorChain) -> np.ndarray:
    """Rule: the chain's free response after each impact, as regressors (``(n, m)``).

    An impact is a run of contact samples, runs closer than :data:`IMPACT_JOIN_DECAYS` decay
    times of the slowest mode joined. The mount's modes span the impact's onset to the
    next impact's onset: the lobes of its ringing that the split took for contact lie
    inside, and the mode, fitted on the samples between them, predicts them, so the next
    split frees them. The low-pass's modes start at the end of the impact's first contact
    run (decaying in a few samples, from the onset they would be ``exp(sigma T)`` larger
    over the contact and swamp the solve). Both modes also span the record's start to the
    first impact (an impact before the record rings into it).
    """
    mount, lowpass = chain_modes(chain)
    n = contact.size
    if not (mount or lowpass):
        return np.zeros((n, 0))
    slowest = min(-p.real for p in (*mount, *lowpass))
    join = max(1, math.ceil(IMPACT_JOIN_DECAYS * fs_hz / slowest))
    joined = ndimage.binary_closing(contact, structure=np.ones(2 * join + 1, bool)) | contact
    impacts = [s[0] for s in ndimage.find_objects(ndimage.label(joined)[0])]
    onsets = [s.start for s in impacts]
    cols = _mode_block(n, 0, onsets[0] if onsets else n, fs_hz, [*mount, *lowpass])
    for span, stop in zip(impacts, [*onsets[1:], n], strict=True):
        cols += _mode_block(n, span.start, stop, fs_hz, mount)
        out = np.flatnonzero(~contact[span.start : span.stop])
        release = span.start + (int(out[0]) if out.size else span.stop - span.start)
        cols += _mode_block(n, release, stop, fs_hz, lowpass)
    return np.column_stack(cols)


def recording_forcing_lines(
    accel: np.ndarray,
    fs_hz: float,
    forcing_hz: float,
    stiffness: float,
    damping: float,
    chain: SensorChain | None = None,
) -> np.ndarray | None:
    """Complex harmonic ratios ``h_m exp(i phi_m)`` of one record, for ``m`` in
    :data:`ORDERS` after the first (None where the record cannot be read).

    Parameters
    ----------
    accel : numpy.ndarray
        Absolute acceleration (either polarity: the spikes tell, :func:`spikes_polarity`).
    fs_hz, forcing_hz : float
        Sampling and forcing frequencies.
    stiffness, damping : float
        ``k = (f_n / f_f)**2`` and ``c = 2 zeta sqrt(k)`` of the free flight in forcing
        radians (eq. 12).
    chain : SensorChain, optional
        The sensor chain the record passed through (the campaign's identified one): its
        free modes after each impact join the regression (see the module notes), and a
        record longer than :data:`WINDOW_PERIODS` periods is read per window (the median).
    """
    period = fs_hz / forcing_hz
    y = np.asarray(accel, dtype=np.float64)
    if not (np.all(np.isfinite(y)) and y.size >= MIN_PERIODS * period and period > 6):
        return None
    y = y * -spikes_polarity(y)  # a sensor mounted the other way would turn phi_2 by pi
    if chain is not None and not any(chain_modes(chain)):
        chain = None
    windows = 1 if chain is None else math.ceil(y.size / (WINDOW_PERIODS * period))
    readings = [
        z
        for part in np.array_split(y, windows)
        if (z := _window_lines(part, fs_hz, forcing_hz, stiffness, damping, chain)) is not None
    ]
    if not readings:
        return None
    z = np.vstack(readings)
    return np.median(z.real, axis=0) + 1j * np.median(z.imag, axis=0)


def _window_lines(
    y: np.ndarray,
    fs_hz: float,
    forcing_hz: float,
    stiffness: float,
    damping: float,
    chain: SensorChain | None,
) -> np.ndarray | None:
    """:func:`recording_forcing_lines` of one stretch of the record (turned to the
    simulator's polarity)."""
    period = fs_hz / forcing_hz
    if y.size < MIN_PERIODS * period:
        return None
    y = y[: periodic_length(y, period)]
    dtau = 2 * np.pi * forcing_hz / fs_hz
    tau = np.arange(y.size) * dtau
    vel, disp = integrate_spectral(y, dtau)
    use = np.ones(y.size, dtype=bool)
    edge = max(1, int(0.25 * period))
    use[:edge] = use[-edge:] = False
    cols = [np.ones_like(tau)]
    for m in ORDERS:
        cols += [np.cos(m * tau), np.sin(m * tau)]
    design = np.column_stack(cols)
    target = -y - stiffness * disp - damping * vel
    coef, free, contact, _ = robust_split(design, target, use)
    for _ in range(RINGING_PASSES if chain is not None else 0):
        modes = free_mode_columns(contact, fs_hz, chain)
        coef, free, new, _ = robust_split(np.hstack([design, modes]), target, use)
        coef = coef[: design.shape[1]]
        if np.array_equal(new, contact):
            break
        contact = new
    if not np.all(np.isfinite(coef)) or free.sum() < 2 * len(cols):
        return None
    lines = -(np.array(ORDERS, float)[:, None] ** 2) * table_motion(
        coef[1:], stiffness, damping, ORDERS
    )  # F_m = -m**2 s_m, as (cos, sin) amplitudes
    # c cos + s sin = R sin(m tau + psi), R exp(i psi) = s + i c; the chain scaled and
    # turned each line by its response there
    z = lines[:, 1] + 1j * lines[:, 0]
    if chain is not None:
        z = z / chain_response(chain, forcing_hz * np.array(ORDERS, float))
    spread = float(np.std(target[free]))
    if not abs(z[0]) > MIN_FUNDAMENTAL * spread:
        return None
    orders = np.array(ORDERS[1:], float)
    return z[1:] / abs(z[0]) * np.exp(-1j * orders * np.angle(z[0]))


def campaign_forcing_lines(
    signals: Sequence[np.ndarray],
    rows: Sequence[ManifestRow],
    sensor: Mapping[str, Any] | None = None,
) -> dict[str, float] | None:
    """Rule: the campaign's shaker harmonics, the median over the readable recordings of
    each harmonic's ``h exp(i phi)`` (see the module notes).

    `sensor` is the chain the campaign's recordings share
    (:func:`~stiffnet.restoring_force.chain.shared_chain`: the restoring-force evidence's
    ``sensor``): its modes are read with the lines (:func:`free_mode_columns`).

    Returns
    -------
    dict or None
        ``second``, ``phase_second``, ``third``, ``phase_third`` (the parameters of
        ``forcing_harmonics``), ``second_se`` and ``third_se`` (standard error of each
        median, the larger of its two Cartesian coordinates', from the recordings' robust
        scatter) and ``read`` (recordings read); None when none could be.
    """
    sheet = shared_chain_sheet(dict(sensor)) if sensor else None
    readings = []
    for accel, row in zip(signals, rows, strict=True):
        ratio = row.frequency_ratio
        if not ratio or not np.isfinite(ratio) or ratio <= 0:
            continue
        fn = natural_frequency(row)
        k = 1.0 / ratio**2
        zeta = DEFAULT_DAMPING if row.damping_ratio is None else float(row.damping_ratio)
        fs = float(row.fs_hz)
        chain = sensor_from_mapping(sheet, fs, fitted_sheet=True) if sheet else None
        z = recording_forcing_lines(accel, fs, fn * ratio, k, 2 * zeta * math.sqrt(k), chain)
        if z is not None:
            readings.append(z)
    if not readings:
        return None
    z = np.vstack(readings)
    mid = np.median(z.real, axis=0) + 1j * np.median(z.imag, axis=0)
    # the median's standard error: 1.2533 sigma / sqrt(n), sigma from 1.4826 MAD
    mad = np.maximum(
        np.median(np.abs(z.real - mid.real), axis=0), np.median(np.abs(z.imag - mid.imag), axis=0)
    )
    se = 1.2533 * 1.4826 * mad / math.sqrt(len(readings))
    return {
        "second": float(abs(mid[0])),
        "phase_second": float(np.angle(mid[0])),
        "third": float(abs(mid[1])),
        "phase_third": float(np.angle(mid[1])),
        "second_se": float(se[0]),
        "third_se": float(se[1]),
        "read": float(len(readings)),
    }
