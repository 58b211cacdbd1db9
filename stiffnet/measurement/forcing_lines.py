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
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from stiffnet.campaign import ManifestRow
from stiffnet.campaign.simulate import natural_frequency
from stiffnet.measurement.nuisance import DEFAULT_DAMPING  # a row that names none
from stiffnet.restoring_force.free_flight import robust_split, table_motion
from stiffnet.restoring_force.reconstruct import integrate_spectral, periodic_length

#: Forcing lines read (1 = the fundamental; the shaker's 2nd and 3rd).
ORDERS = (1, 2, 3)
#: Whole forcing periods a record must hold to be read (the integration needs several).
MIN_PERIODS = 4
#: A recording's reading is kept when its fundamental carries at least this share of the
#: free-flight target's spread (otherwise the flights are too short or too noisy to say).
MIN_FUNDAMENTAL = 0.2


def spikes_polarity(accel: np.ndarray) -> int:
    """-1 where the record's extreme excursions (the contact spikes) point down (the
    simulator's polarity: contact forces push ``-accel`` up), else +1."""
    med = float(np.median(accel))
    lo, hi = np.percentile(accel, [0.5, 99.5])
    return -1 if med - lo >= hi - med else 1


def recording_forcing_lines(
    accel: np.ndarray, fs_hz: float, forcing_hz: float, stiffness: float, damping: float
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
    """
    period = fs_hz / forcing_hz
    y = np.asarray(accel, dtype=np.float64)
    if not (np.all(np.isfinite(y)) and y.size >= MIN_PERIODS * period and period > 6):
        return None
    y = y * -spikes_polarity(y)  # a sensor mounted the other way would turn phi_2 by pi
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
    coef, free, _, _ = robust_split(design, target, use)
    if not np.all(np.isfinite(coef)) or free.sum() < 2 * len(cols):
        return None
    lines = -(np.array(ORDERS, float)[:, None] ** 2) * table_motion(
        coef[1:], stiffness, damping, ORDERS
    )  # F_m = -m**2 s_m, as (cos, sin) amplitudes
    level = np.hypot(lines[:, 0], lines[:, 1])
    spread = float(np.std(target[free]))
    if not level[0] > MIN_FUNDAMENTAL * spread:
        return None
    psi = np.arctan2(lines[:, 0], lines[:, 1])  # c cos + s sin = R sin(m tau + psi)
    orders = np.array(ORDERS[1:], float)
    return level[1:] / level[0] * np.exp(1j * (psi[1:] - orders * psi[0]))


def campaign_forcing_lines(
    signals: Sequence[np.ndarray], rows: Sequence[ManifestRow]
) -> dict[str, float] | None:
    """Rule: the campaign's shaker harmonics, the median over the readable recordings of
    each harmonic's ``h exp(i phi)`` (see the module notes).

    Returns
    -------
    dict or None
        ``second``, ``phase_second``, ``third``, ``phase_third`` (the parameters of
        ``forcing_harmonics``), ``second_se`` and ``third_se`` (standard error of each
        median, the larger of its two Cartesian coordinates', from the recordings' robust
        scatter) and ``read`` (recordings read); None when none could be.
    """
    readings = []
    for accel, row in zip(signals, rows, strict=True):
        ratio = row.frequency_ratio
        if not ratio or not np.isfinite(ratio) or ratio <= 0:
            continue
        fn = natural_frequency(row)
        k = 1.0 / ratio**2
        zeta = DEFAULT_DAMPING if row.damping_ratio is None else float(row.damping_ratio)
        z = recording_forcing_lines(accel, float(row.fs_hz), fn * ratio, k, 2 * zeta * math.sqrt(k))
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
