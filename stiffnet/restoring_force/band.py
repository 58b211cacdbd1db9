"""The band a record carries: what a chain's inverse keeps, and whether "no contact" can be
read (contacts a low-pass smoothed away still leave harmonics).

**What the inverse keeps** (:func:`kept_band`). A known chain is divided out within the band
the record supports (:func:`~.chain.deconvolve`: the Wiener weight switches the inverse off
where the record sinks under its noise, the gain is capped); the deconvolved record is the
true acceleration through the product of the chain and that inverse. The contact law is fitted
forward through that product (:func:`~.contact_law.fit_contact_law`'s ``band``), so what the
noise took from the pulses is taken from the law's force as well.

**A low-pass below the contact** (:func:`lowpass_refusal`). Fitted forward through that
band, the law does not need the inverse to pass the contact's frequency: below the corner
the pulses keep their area, and the band's bend of their spectrum still carries the
contact's frequency. Information is not what runs out first: the Cramér-Rao half-width
(90 %) of beta through 2nd- and 4th-order low-passes at 0.6-0.97 contact frequencies, at
2 % noise, is 0.3-1.7 % (docs/crosscheck.md), yet readings there can be 20 % off. The
readings that went wrong below the corner read their contact confidently above it; the
right ones near the corner carry intervals that reach below it. So the refusal stands where
the low end of the reading's interval is beyond the corner, and where the interval reaches
a contact the low-pass passes the reading stands with that interval.

**"No contact"** (:func:`smoothed_contact_refusal`).

A linear free flight driven by the table (eq. 12 with ``H = 0``, the table's motion at the
forcing harmonics :data:`~.free_flight.HARMONICS`) answers at those harmonics only. Impacts
add every harmonic of the forcing up to about the contact's frequency; a low-pass below the
contact's frequency rounds the pulses until none stands above the free-flight scatter (the
map finds no excursion), yet the harmonics it passes remain, periodic and far above the
record's noise. Such harmonics on a record the map reads as free flight mean the band does
not carry the contact: "no contact" would be a silent wrong answer. A one-sided force (a
contact) gives even and odd harmonics alike; a symmetric nonlinearity of the free flight
(dry friction) gives odd ones only, and is no sign of a contact.
"""

from __future__ import annotations

import numpy as np

from stiffnet.restoring_force.chain import (
    MIN_LOWPASS_RATIO,
    SensorChain,
    chain_response,
    wiener_gain,
)
from stiffnet.restoring_force.free_flight import HARMONICS
from stiffnet.restoring_force.reconstruct import periodic_length

#: A harmonic stands out when its power exceeds this many times the median of its
#: neighbouring bins (white noise: the median is 0.69 of the mean, so the chance of a noise
#: bin above it is about exp(-0.69 * 100)). Low-passed impact records: 1e2-1e7 at harmonics
#: 4-10; free flights, with or without the shaker's 2nd and 3rd: 0-5.
HARMONIC_RATIO = 100.0
#: ... and at least this many harmonics beyond the free-flight law's must, even and odd
#: ones among them (one could be an interfering line, such as the mains, that happens to
#: fall on a harmonic).
MIN_HARMONICS = 2
#: Neighbour bins on each side that set a harmonic's noise floor, beyond the Hann window's
#: main lobe (+-2 bins: a start-up transient or a forcing frequency read a little off
#: leaks into it).
NEIGHBOURS = 11
LOBE = 2


def excess_harmonics(
    y: np.ndarray, period: float, floor_of: np.ndarray | None = None
) -> np.ndarray:
    """The forcing harmonics beyond the free-flight law's that stand out of the noise.

    Parameters
    ----------
    y : numpy.ndarray
        The record over whole forcing periods (as :func:`~.reconstruct.periodic_length`
        cuts it).
    period : float
        Samples per forcing period.
    floor_of : numpy.ndarray, optional
        The signal, as long as `y`, whose neighbouring bins set each harmonic's noise floor
        (default `y`): a fit's residual is judged against the record's own noise, not
        against its own floor, which a misfit raises.

    Returns
    -------
    numpy.ndarray
        The harmonic numbers (beyond ``max(HARMONICS)``) whose power exceeds
        :data:`HARMONIC_RATIO` times their neighbours' median; empty where the record spans
        too few periods for neighbours between the harmonics (8).
    """
    n = y.size
    periods = n / period
    reach = min(NEIGHBOURS, int(np.floor(periods / 2)))
    if reach < LOBE + 3:
        return np.array([], dtype=int)
    window = np.hanning(n)
    power = np.abs(np.fft.rfft((y - np.mean(y)) * window)) ** 2
    ref = floor_of if floor_of is not None else y
    noise = power if ref is y else np.abs(np.fft.rfft((ref - np.mean(ref)) * window)) ** 2
    offsets = np.r_[-reach:-LOBE, LOBE + 1 : reach + 1]
    out = []
    for m in range(max(HARMONICS) + 1, int((power.size - 1 - reach) / periods) + 1):
        k = int(round(m * periods))
        floor = float(np.median(noise[k + offsets]))
        if power[k] > HARMONIC_RATIO * max(floor, 1e-300):
            out.append(m)
    return np.array(out, dtype=int)


def contact_harmonics(found: np.ndarray) -> bool:
    """Rule: whether standing-out harmonics (:func:`excess_harmonics`) are a one-sided
    force's: at least :data:`MIN_HARMONICS`, even and odd ones among them."""
    return bool(found.size >= MIN_HARMONICS and np.any(found % 2 == 0) and np.any(found % 2 == 1))


def smoothed_contact_refusal(
    y: np.ndarray,
    period: float,
    fs_hz: float,
    natural_hz: float,
    beta_min: float,
    beta_max: float = 100.0,
    sheet_lowpass_hz: float | None = None,
) -> str:
    """Rule: the one-line refusal for a record read as free flight whose harmonics beyond the
    free-flight law's stand out (at least :data:`MIN_HARMONICS`, even and odd), else ''.

    Two things hide contacts that are there: a low-pass below their frequency, and contacts
    too soft or shallow for their force to stand out of the free-flight law the map fits
    (the independent rig's beta 5.8, ideal sensor and no noise, reads so). Where the chain
    is known (a data sheet, or a campaign's pooled chain) and its low-pass passes every
    contact up to `beta_max`, the reason names the contacts alone ("from this record");
    otherwise it names both ("from this sensor": the low-pass may be the sensor's).

    Parameters
    ----------
    y, period
        As :func:`excess_harmonics`.
    fs_hz, natural_hz : float
        Sampling rate and the free flight's natural frequency (Hz).
    beta_min, beta_max : float
        The least and greatest beta of a contact (the classes' edges): the contact's
        frequency is ``f_n sqrt(1 + beta)`` between them.
    sheet_lowpass_hz : float, optional
        The known chain's low-pass corner (``inf``: it has none in the band); None where the
        chain is not known (fitted or unread).
    """
    found = excess_harmonics(y, period)
    if not contact_harmonics(found):
        return ""
    ff = fs_hz / period
    slowest = natural_hz * np.sqrt(1.0 + beta_min)
    fastest = natural_hz * np.sqrt(1.0 + beta_max)
    seen = (
        f"no impact stands out of the free-flight law, yet harmonics {found.min()}-"
        f"{found.max()} of the forcing (up to {found.max() * ff:.0f} Hz) do, which a free "
        "flight lacks"
    )
    if band_passes_contacts(sheet_lowpass_hz, natural_hz, beta_max):
        passes = "none in the band" if np.isinf(sheet_lowpass_hz) else f"{sheet_lowpass_hz:.0f} Hz"
        return (
            f"{seen}: the given chain's low-pass ({passes}) passes every contact up to "
            f"beta {beta_max:g} ({fastest:.0f} Hz), so the contacts are too soft or shallow "
            "to stand out of the free flight: beta is not identifiable from this record"
        )
    return (
        f"{seen}: the contacts are too soft or shallow to stand out of it, or a low-pass below "
        f"the contact's frequency (at least {slowest:.0f} Hz) smooths them away, so beta is "
        "not identifiable from this sensor"
    )


def smoothed_away_refusal(lowpass_hz: float | None, natural_hz: float, beta_max: float) -> str:
    """Rule: the one-line refusal of "no contact" behind a low-pass below the stiffest
    contact's frequency, ``f_n sqrt(1 + beta_max)``, else ''.

    Where the record shows no contact at all (no impact stands out, no harmonics of a
    one-sided force, :func:`smoothed_contact_refusal`), there is no contact of its own to
    compare the low-pass with: only the stiffest the classes allow. Where it shows harmonics,
    the caller compares the low-pass with the contact the joint fit reads instead
    (:func:`lowpass_refusal`).

    Parameters
    ----------
    lowpass_hz : float or None
        The chain's low-pass corner (None or ``inf``: none in the band).
    natural_hz : float
        The free flight's natural frequency (Hz).
    beta_max : float
        The greatest beta of a contact (the classes' top).
    """
    fastest = natural_hz * float(np.sqrt(1.0 + beta_max))
    if not lowpass_hz or not lowpass_hz < fastest:
        return ""
    return (
        f"the low-pass at {lowpass_hz:.0f} Hz is below the contact's frequency {fastest:.0f} Hz "
        f"(beta {beta_max:g}): no contact cannot be told from a contact this sensor smooths away"
    )


def chain_free_reading(
    record: np.ndarray, residual: np.ndarray, period: float, beta_high: float, beta_min: float
) -> bool:
    """Rule: whether contacts that do not stand out, read by the joint fit of
    :mod:`.soft_contact` with no chain known, are the record's alone: the joint law (free
    flight and a Kelvin-Voigt contact, through no sensor) leaves no harmonics of a one-sided
    force (:func:`contact_harmonics`) standing out of the record's own noise, and its
    interval reaches the softest class.

    A low-pass below the contact's frequency rounds the pulses into a shape a softer linear
    contact fits only roughly: the joint law's residual keeps the forcing's harmonics, and
    the reading falls below the classes (stiffnet's simulator behind low-passes at 0.01-0.06
    fs, no other stage: every joint reading left harmonics 4 and beyond 550-1.2e6 times the
    record's floor, and read 0.2-2.5 for contacts of beta 6.5-90; elastic and damped soft
    contacts with no sensor left none above 60 times it, docs/crosscheck.md). A record the
    joint law explains to its noise needs no chain, so the smoothed-contact refusal's
    low-pass is not the record's.

    Parameters
    ----------
    record, residual : numpy.ndarray
        The record the joint fit read and its residual, on the same used samples.
    period : float
        Samples per forcing period.
    beta_high : float
        The high end of the joint reading's interval.
    beta_min : float
        The softest class's least beta.
    """
    n = periodic_length(record, period)
    left = excess_harmonics(residual[:n], period, floor_of=record[:n])
    return not contact_harmonics(left) and beta_high >= beta_min


def band_passes_contacts(
    sheet_lowpass_hz: float | None, natural_hz: float, beta_max: float = 100.0
) -> bool:
    """Rule: whether a known chain's low-pass (``inf``: none in the band; None: the chain is
    not known) passes every contact up to `beta_max`, ``f_n sqrt(1 + beta_max)``: then
    contacts that do not stand out are the record's, not the sensor's."""
    fastest = natural_hz * np.sqrt(1.0 + beta_max)
    return sheet_lowpass_hz is not None and sheet_lowpass_hz >= fastest


def kept_band(y: np.ndarray, fs_hz: float, chain: SensorChain, noise_sigma: float) -> np.ndarray:
    """The response, per ``rfft`` bin of `y`, from the true acceleration to the record with
    the chain divided out (:func:`~.chain.deconvolve` of `y` with the same arguments): the
    chain's analog response times its Wiener-weighted, capped inverse; 1 at zero frequency.

    Parameters
    ----------
    y : numpy.ndarray
        The record as recorded (the inverse's weight reads its power).
    fs_hz : float
    chain : SensorChain
    noise_sigma : float
        Standard deviation of the record's white noise (the free flight's scatter).
    """
    h = chain_response(chain, np.fft.rfftfreq(y.size, 1.0 / fs_hz))
    band = wiener_gain(y, h, noise_sigma**2) * h
    band[0] = 1.0
    return band


def lowpass_refusal(chain: SensorChain, natural_hz: float, beta_low: float) -> str:
    """Rule: the one-line refusal where a known chain's low-pass sits below the contact's
    frequency at every beta the reading leaves open, else ''.

    Through a known chain the law is fitted through the band its inverse keeps
    (:func:`kept_band`): below the low-pass the pulses keep their area and the band's bend
    of their spectrum still carries the contact's frequency. Where the reading's interval
    reaches a contact the low-pass passes (``f_n sqrt(1 + beta_low)`` at or under the
    corner), the band is not shown to cut the contact, and the reading stands with that
    interval; where even its low end is above the corner, the band cuts it.

    Parameters
    ----------
    chain : SensorChain
        The known chain, its ``contact_hz`` the contact's frequency the law fitted through
        its band reads.
    natural_hz : float
        The free flight's natural frequency (Hz).
    beta_low : float
        The low end of the reading's interval.
    """
    fl, fc = chain.lowpass_hz, chain.contact_hz
    if not fl or not fc or fl >= MIN_LOWPASS_RATIO * fc:
        return ""
    lowest = natural_hz * np.sqrt(1.0 + max(beta_low, 0.0))
    if not np.isfinite(lowest):  # no interval: the reading alone
        lowest = fc
    if fl >= MIN_LOWPASS_RATIO * lowest:
        return ""
    return (
        f"the low-pass at {fl:.0f} Hz is below the contact's frequency {fc:.0f} Hz (at least "
        f"{lowest:.0f} Hz): beta is not identifiable from this sensor"
    )


def fitted_lowpass_refusal(chain: SensorChain | None, natural_hz: float, beta_high: float) -> str:
    """Rule: the one-line refusal where a fitted, applied chain's low-pass sits below the
    contact at the top of the reading's interval, else ''.

    A fitted chain's contact and low-pass are read from the same pulses, and the fit can
    trade the contact's speed for its damping (a 71 Hz 3rd-order low-pass in front of a
    66 Hz elastic contact fitted as an 81 Hz low-pass behind a 52 Hz contact of damping
    0.87). Where the betas the reading leaves open reach a contact above that low-pass
    (``f_n sqrt(1 + beta_high)``), the band is not shown to pass the contact, the reverse of
    a data sheet's (:func:`lowpass_refusal`, which knows its corner and refuses only where
    even the interval's low end lies beyond it).
    """
    if chain is None or chain.source != "fitted" or not chain.applied or not chain.lowpass_hz:
        return ""
    top = natural_hz * np.sqrt(1.0 + max(beta_high, 0.0))
    if not np.isfinite(top) or chain.lowpass_hz >= MIN_LOWPASS_RATIO * top:
        return ""
    return (
        f"the low-pass at {chain.lowpass_hz:.0f} Hz is below the contact's frequency at the "
        f"top of beta's interval ({top:.0f} Hz): beta is not identifiable from this sensor"
    )
