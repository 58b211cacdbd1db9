"""The accelerometer's chain identified from the impacts, and undone within the band it passes.

Every impact is a known kind of input. In contact a Kelvin-Voigt restraint and the
free spring act in parallel, so the contact force is the damped oscillation::

    F(t) = v0 exp(-s t) [ K / w_d sin(w_d t) + c_c (cos(w_d t) - s / w_d sin(w_d t)) ]

from the onset (``d = 0``, ``d' = v0``) until it first returns to zero (the
restraint never pulls), with ``w_d^2 + s^2 = W^2 = k + K``, ``c_c ~ 2 s`` and
``K = W^2 - k``: its shape is set by the contact frequency ``W / 2 pi`` and
damping ratio ``s / W`` alone, its size by the impact velocity ``v0``. The
recorded acceleration is that force through the sensor chain (mounted resonance
``w_r^2 / (s^2 + 2 z_r w_r s + w_r^2)``, Butterworth anti-alias low-pass of some
order at ``f_l``): the free-flight law's residual around each impact
(:mod:`.free_flight`) is ``v0_i (h * F)(t - t0_i)`` plus a slow baseline.
:func:`fit_chain` fits that model to all the impacts of a record at once
(shared contact shape and chain; per impact onset, size, a linear baseline and the
velocity step a mis-fitted free-flight damping leaves, the linear ones by variable
projection), for each chain structure (none, the
resonance, the low-pass of order 1-4, both), and keeps the structure of least
BIC. Intervals come from the fit's Jacobian.

:func:`deconvolve` divides the record by the identified chain's response within
the band the data support (a Wiener gain from the record's own noise floor,
:func:`wiener_gain`), so that the force-displacement map downstream sees the
contact force; :func:`identifiability` refuses where the low-pass sits below the
contact's own frequency (there the contact's shape, hence beta, is the filter's).
The charge amplifier's high-pass is not part of this fit: a first-order
high-pass leaves a short pulse untouched and is identified with the free-flight
law instead (:mod:`.sensor`).

References: Worden & Tomlinson, *Nonlinearity in Structural Dynamics* (ch. 7,
restoring force); the paper's eqs 11-12 (the contact law).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import ndimage, optimize, signal, sparse, stats

from stiffnet.restoring_force.contact_law import force_unit
from stiffnet.restoring_force.kept_fits import kept

#: Fine-grid oversampling of the pulse model (the chain as the analog one it discretises).
OVERSAMPLE = 16
#: Most impacts one fit uses (the largest); bounds the cost.
MAX_IMPACTS = 8
#: The mount's resonance is at least this many times the contact's frequency (slower
#: ringing is the contact's own oscillation).
MIN_RESONANCE_RATIO = 1.5
#: The chain-free pulse fit within this factor of the noise variance ends the search (ideal
#: records: 0.2-0.7; a chain that matters to beta: 3-50).
NOISE_FLOOR = 2.0
#: The contact's half period is at most this many times its core's duration.
MAX_HALF_PERIODS = 2.5
#: The contact is at least this fraction of the plain map's contact frequency.
PLAIN_CONTACT_FRACTION = 0.8
#: ... unless the impacts last more than this many of that law's half periods: then the plain
#: map read a mount's ring as the contact (a ring reads it stiffer, not softer). Measured on the
#: independent rig: 1.0-2.6 behind low-passes of 70-120 Hz, a 417 Hz resonance or no chain;
#: 11 and 20 behind a 187 Hz resonance (zeta 0.076) whose 62 Hz contact maps as 152-269 Hz.
PLAIN_RING_HALF_PERIODS = 5.0
#: Points of the coarse grid that starts each stage.
GRID = 12
#: A mount's resonance is lightly damped (0.01-0.1 on sensors): a better damped pair is a
#: low-pass's (a Butterworth's lightest: 0.38 at order 4), which a free resonance would mimic.
MAX_RESONANCE_DAMPING = 0.15
#: ... and not undamped: below this a fitted "resonance" rings on through the window only to
#: mimic a steep low-pass's overshoot (a sensor's Q of +36 dB is 0.008).
MIN_RESONANCE_DAMPING = 0.008
#: Function evaluations per least-squares start.
MAX_NFEV = 40
#: Low-pass orders tried.
ORDERS = (1, 2, 3, 4)
#: Corners at or above this fraction of fs barely touch the record: reported as none.
MAX_CORNER_FRACTION = 0.45
#: A chain stage is kept when it lowers the BIC by at least this much and leaves at most this
#: fraction of the simpler structure's squared residual (the contact model is not exact: at
#: 2 % noise a wrong extra stage buys a few per cent of it; a real one, half or more).
MIN_BIC_GAIN = 10.0
STAGE_GAIN = 0.7
#: Nominal coverage of the reported intervals.
COVERAGE = 0.9
#: The Wiener gain of the inverse is capped at this amplification.
MAX_GAIN = 30.0
#: Spectral subtraction's over-subtraction factor (how far above the noise floor a bin must
#: rise before the inverse acts on it): 1, the Wiener filter. Larger values cut into the
#: contact's band (beta 30 read 27 through a 4th-order low-pass at 0.1 fs with 1.5-4).
OVER_SUBTRACTION = 1.0
#: The top of the band whose periodogram gives the white-noise floor (fraction of Nyquist).
NOISE_BAND = 0.75
#: A low-pass corner below this multiple of the contact frequency refuses beta.
MIN_LOWPASS_RATIO = 1.0
#: The low-pass the impacts cannot exclude: corners tried (in contact frequencies, up to the
#: band's edge) and orders (the lab range's gentlest and steepest) of the profile.
PROFILE_CORNERS = np.geomspace(1.2, 12.0, 8)
PROFILE_ORDERS = (2, 4)
#: Function evaluations per profile point (a shorter fit only overstates its residual, so the
#: profile stays on the side of excluding less than it could).
PROFILE_NFEV = 15


@dataclass(frozen=True)
class SensorChain:
    """A sensor chain: mounted resonance, anti-alias low-pass, charge-amplifier high-pass.

    Attributes
    ----------
    resonance_hz, resonance_damping : float or None
        Mounted resonance and its damping ratio (None: none in the band).
    lowpass_hz : float or None
        Butterworth corner (None: none in the band).
    lowpass_order : int or None
    highpass_hz : float
        First-order high-pass corner (0: none).
    source : str
        ``"fitted"`` (from the record) or ``"data sheet"`` (given).
    fitted_sheet : bool
        A data sheet whose values were themselves fitted to recordings, not read off the
        accelerometer's calibration sheet: a campaign's pooled chain (profiled over its
        contact laws' R², :mod:`serving.campaign_chain`), ``diagnose``'s shared chain, the
        chain a log's first check fitted. Read as a data sheet, but its inverse is weighted
        as a fitted chain's (:func:`inverse_noise_sigma`). Not reported (the callers name
        such a chain's source themselves).
    intervals : dict
        ``name -> [low, high]`` at :data:`COVERAGE` for the fitted quantities.
    contact_hz, contact_damping : float or None
        The contact's own frequency ``W / 2 pi`` and damping ratio the fit gives.
    applied : bool
        Whether the map was read through its inverse (a fitted chain whose inverse leaves the
        contact law worse than the record as recorded is reported, not applied).
    lowpass_not_excluded : tuple of (order, Hz)
        Per order of :data:`PROFILE_ORDERS`, the lowest low-pass corner the impacts fit as
        well as the chosen chain within :data:`COVERAGE` (:meth:`_ChainSearch.lowpass_profile`):
        a low-pass the fit cannot see but that may still bend beta (fitted chains only).
    """

    resonance_hz: float | None = None
    resonance_damping: float | None = None
    lowpass_hz: float | None = None
    lowpass_order: int | None = None
    highpass_hz: float = 0.0
    source: str = "fitted"
    fitted_sheet: bool = False
    intervals: dict[str, list[float]] = field(default_factory=dict)
    contact_hz: float | None = None
    contact_damping: float | None = None
    applied: bool = True
    lowpass_not_excluded: tuple[tuple[int, float], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready summary."""

        def num(v: float | None) -> float | None:
            return float(v) if v is not None and np.isfinite(v) else None

        return {
            "resonance_hz": num(self.resonance_hz),
            "resonance_damping": num(self.resonance_damping),
            "lowpass_hz": num(self.lowpass_hz),
            "lowpass_order": int(self.lowpass_order) if self.lowpass_order else None,
            "highpass_hz": num(self.highpass_hz),
            "source": self.source,
            "intervals": {k: [float(a), float(b)] for k, a, b in
                          ((k, *v) for k, v in self.intervals.items())},
            "contact_hz": num(self.contact_hz),
            "contact_damping": num(self.contact_damping),
            "applied": self.applied,
            "lowpass_not_excluded": [{"order": int(o), "hz": float(f)}
                                     for o, f in self.lowpass_not_excluded],
        }  # fmt: skip

    @property
    def has_dynamics(self) -> bool:
        """Whether a resonance or a low-pass is in the band (what :func:`deconvolve` undoes)."""
        return bool(self.resonance_hz) or bool(self.lowpass_hz)


#: The keys of a sensor data sheet.
SENSOR_KEYS = ("resonance_hz", "resonance_damping", "lowpass_hz", "lowpass_order", "highpass_hz")
#: ... and the optional ends of its high-pass corner's interval (a campaign's profiled corner,
#: :func:`serving.campaign_chain.campaign_highpass`): beta's interval spans the readings there.
HIGHPASS_ENDS = ("highpass_low_hz", "highpass_high_hz")
#: ... and of its low-pass corner's (a campaign's profiled low-pass,
#: :func:`serving.campaign_chain.campaign_lowpass`), at the sheet's order.
LOWPASS_ENDS = ("lowpass_low_hz", "lowpass_high_hz")


def parse_sensor_option(text: str, what: str = "--sensor") -> dict[str, float]:
    """``KEY=VALUE,...`` (the CLI's ``--sensor``; ``;`` also separates, for a manifest's cell)
    as a mapping; the keys are checked by :func:`sensor_from_mapping`.

    Raises
    ------
    ConfigError
        One line starting with `what`, for an item without ``=`` or a value that is not a
        number.
    """
    from stiffnet.errors import ConfigError

    keys = ", ".join(SENSOR_KEYS)
    out: dict[str, float] = {}
    for item in (p.strip() for p in text.replace(";", ",").split(",") if p.strip()):
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"{what}: {item!r} is not KEY=VALUE (keys: {keys})")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"{what}: {key.strip()} = {value!r} is not a number") from None
    if not out:
        raise ConfigError(f"{what}: empty (give KEY=VALUE,... with keys {keys})")
    return out


def sensor_sheet(text: str, fs_hz: float, what: str = "sensor") -> dict[str, float]:
    """A data sheet written as text (``--sensor``, a manifest's ``sensor`` cell) read and
    checked: the mapping :func:`sensor_from_mapping` accepts, or one :class:`ConfigError` line
    starting with `what` that names the bad item or key."""
    from stiffnet.errors import ConfigError

    sheet = parse_sensor_option(text, what)
    try:
        sensor_from_mapping(sheet, fs_hz)
    except ValueError as exc:
        raise ConfigError(f"{what}: {exc}") from None
    return sheet


#: A data sheet's ``highpass_hz`` that asks for the record's own corner (fitted as without a
#: sheet): a campaign's pooled chain knows the shared resonance and low-pass, but the
#: recordings' high-pass fits scatter too much to pool (0-4 Hz for a true 3.6 Hz), and a
#: sheet's 0 would hold the map at no high-pass (beta 0.9 off on the rig).
HIGHPASS_FITTED = "auto"


def sheet_fits_highpass(data: dict[str, Any] | None) -> bool:
    """Whether a data sheet leaves the high-pass corner to the record (:data:`HIGHPASS_FITTED`)."""
    return bool(data) and data.get("highpass_hz") == HIGHPASS_FITTED


def sensor_from_mapping(
    data: dict[str, Any], fs_hz: float, fitted_sheet: bool = False
) -> SensorChain:
    """A data-sheet chain from ``resonance_hz``, ``resonance_damping``, ``lowpass_hz``,
    ``lowpass_order``, ``highpass_hz`` (any left out or 0: no such stage; ``highpass_hz``
    :data:`HIGHPASS_FITTED`: the record's own corner, fitted by the caller, 0 here), and
    optionally the ends of the corner's interval (:data:`HIGHPASS_ENDS`, both holding it:
    the chain's ``intervals["highpass_hz"]``) and of the low-pass corner's
    (:data:`LOWPASS_ENDS`: ``intervals["lowpass_hz"]``). `fitted_sheet`: the values were
    fitted to recordings (:attr:`SensorChain.fitted_sheet`), not given by the user.

    Raises
    ------
    ValueError
        With one line naming the key, for an unknown key or a value out of range.
    """
    known = set(SENSOR_KEYS) | set(HIGHPASS_ENDS) | set(LOWPASS_ENDS)
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"unknown sensor key(s) {', '.join(unknown)}; known: {sorted(known)}")

    def number(key: str, low: float, high: float) -> float:
        v = data.get(key) or 0.0
        if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v):
            raise ValueError(f"sensor {key} must be a number, got {v!r}")
        if v and not low <= v <= high:
            raise ValueError(f"sensor {key} = {v:g} is outside [{low:g}, {high:g}]")
        return float(v)

    fr = number("resonance_hz", 1e-3, 1e7)
    zr = number("resonance_damping", 1e-4, 1.0) or (0.03 if fr else 0.0)
    fl = number("lowpass_hz", 1e-3, 1e7)
    order = number("lowpass_order", 1, 8) or (2 if fl else 0)
    if order != int(order):
        raise ValueError(f"sensor lowpass_order must be an integer, got {order:g}")
    fh = 0.0 if sheet_fits_highpass(data) else number("highpass_hz", 0.0, 1e3)
    ends = [number(k, 0.0, 1e3) for k in HIGHPASS_ENDS]
    if any(k in data for k in HIGHPASS_ENDS) and not (fh and ends[0] <= fh <= ends[1]):
        raise ValueError(f"sensor {' and '.join(HIGHPASS_ENDS)} must hold highpass_hz between "
                         f"them, got {ends[0]:g}, {fh:g}, {ends[1]:g}")  # fmt: skip
    low_ends = [number(k, 1e-3, 1e7) for k in LOWPASS_ENDS]
    has_low_ends = any(k in data for k in LOWPASS_ENDS)
    if has_low_ends and not (fl and low_ends[0] <= fl <= low_ends[1]):
        raise ValueError(f"sensor {' and '.join(LOWPASS_ENDS)} must hold lowpass_hz between "
                         f"them, got {low_ends[0]:g}, {fl:g}, {low_ends[1]:g}")  # fmt: skip
    in_band = 0.5 * fs_hz
    intervals = {"highpass_hz": ends} if any(k in data for k in HIGHPASS_ENDS) else {}
    if has_low_ends and 0 < fl < in_band:
        intervals["lowpass_hz"] = low_ends
    return SensorChain(
        resonance_hz=fr if 0 < fr < in_band else None,
        resonance_damping=zr if 0 < fr < in_band else None,
        lowpass_hz=fl if 0 < fl < in_band else None,
        lowpass_order=int(order) if 0 < fl < in_band else None,
        highpass_hz=fh,
        source="data sheet",
        fitted_sheet=fitted_sheet,
        intervals=intervals,
    )


def chain_sos(chain: SensorChain, fs_hz: float) -> np.ndarray | None:
    """Digital sections of the chain's resonance and low-pass at rate `fs_hz` (bilinear,
    prewarped: the corners land where the analog ones are), or None without either."""
    stages = []
    if chain.resonance_hz and chain.resonance_hz < 0.5 * fs_hz:
        stages.append(_resonance_stage(chain.resonance_hz, chain.resonance_damping, fs_hz))
    if chain.lowpass_hz and chain.lowpass_hz < 0.5 * fs_hz:
        stages.append(_lowpass_stage(chain.lowpass_order, chain.lowpass_hz, fs_hz))
    return np.vstack(stages) if stages else None


# Each stage is kept per its values (read-only; chain_sos stacks a copy): a chain fit's
# finite-difference Jacobian moves one parameter at a time, so most of its evaluations
# design stages already designed, and scipy's design cost as much as the filtering.
@functools.lru_cache(maxsize=4096)
def _resonance_stage(resonance_hz: float, damping: float, fs_hz: float) -> np.ndarray:
    w = 2.0 * fs_hz * np.tan(np.pi * resonance_hz / fs_hz)
    poles = np.roots([1.0, 2.0 * damping * w, w * w])
    if 0.0 < damping < 1.0:  # one pair of complex poles
        fs2 = 2.0 * fs_hz
        gain = (w * w) * np.real(1.0 / np.prod(fs2 - poles))
        sos = _pair_section((fs2 + poles) / (fs2 - poles), gain)
    else:
        sos = signal.zpk2sos(*signal.bilinear_zpk([], poles, w * w, fs_hz))
    sos.setflags(write=False)
    return sos


#: The analog second-order Butterworth prototype's poles (scipy's ``buttap(2)``).
_BUTTERWORTH2 = signal.buttap(2)[1]


@functools.lru_cache(maxsize=4096)
def _lowpass_stage(order: int, lowpass_hz: float, fs_hz: float) -> np.ndarray:
    if order == 2 and 0.0 < lowpass_hz < 0.5 * fs_hz:  # the fit's own low-pass: one pair
        wo = float(4.0 * np.tan(np.pi * (lowpass_hz / (fs_hz / 2)) / 2.0))
        poles = wo * _BUTTERWORTH2
        gain = wo**2 * np.real(1.0 / np.prod(4.0 - poles))
        sos = _pair_section((4.0 + poles) / (4.0 - poles), gain)
    else:
        sos = signal.butter(order, lowpass_hz, fs=fs_hz, output="sos")
    sos.setflags(write=False)
    return sos


def _pair_section(poles_z: np.ndarray, gain: float) -> np.ndarray:
    """The section of a pair of complex digital poles and two zeros at Nyquist: scipy's
    ``zpk2sos`` of the bilinear transform's output, its own arithmetic step for step (the
    same bits, tests/test_restoring_force_chain_cost.py) without the general pairing's
    Python, 5-15 times the arithmetic's cost (a chain fit designs a stage at most
    evaluations: a step in the contact frequency moves the resonance too)."""
    p1 = poles_z[np.argmax(poles_z.imag)]
    den = np.convolve(np.convolve(np.ones(1, complex), np.array([1.0, -p1])),
                      np.array([1.0, -p1.conjugate()])).real  # fmt: skip
    return np.array([[gain * 1.0, gain * 2.0, gain * 1.0, den[0], den[1], den[2]]])


#: The record is read from where the low-pass has settled: this many of its DC group delays.
SETTLE_DELAYS = 3.0


def settling_samples(chain: SensorChain | None, fs_hz: float) -> int:
    """Samples a chain's low-pass needs to settle when it starts from rest with the logger.

    An analog chain switched on with the record starts its fast stages from zero: for about
    their group delay the record is no filtered copy of the motion, and the acceleration's
    area it lacks there becomes a velocity step that the periodic integrals spread over the
    whole record (the high-pass corner then reads 0.8-0.9 of the truth). The low-pass's step
    response has delivered its area after a few DC group delays (:data:`SETTLE_DELAYS`); a
    resonance's start-up ring carries almost none (``2 zeta / w_r``) and is not counted.
    0 without a low-pass in the band.
    """
    if chain is None:
        return 0
    stages = [*chain.lowpass_not_excluded]
    if chain.lowpass_hz:
        stages.append((chain.lowpass_order or 2, chain.lowpass_hz))
    delay = 0.0
    for order, hz in stages:
        if hz < 0.5 * fs_hz:
            sos = signal.butter(int(order), hz, fs=fs_hz, output="sos")
            delay = max(delay, float(signal.group_delay(signal.sos2tf(sos), w=[1e-4])[1][0]))
    return int(np.ceil(SETTLE_DELAYS * delay))


def chain_response(chain: SensorChain, freqs_hz: np.ndarray) -> np.ndarray:
    """The analog chain's complex response (resonance x low-pass) at `freqs_hz`."""
    s = 2j * np.pi * np.asarray(freqs_hz, dtype=float)
    h = np.ones_like(s)
    if chain.resonance_hz:
        wr = 2 * np.pi * chain.resonance_hz
        h = h * wr**2 / (s**2 + 2 * chain.resonance_damping * wr * s + wr**2)
    if chain.lowpass_hz:
        b, a = signal.butter(chain.lowpass_order, 2 * np.pi * chain.lowpass_hz, analog=True)
        h = h * np.polyval(b, s) / np.polyval(a, s)
    return h


def wiener_gain(y: np.ndarray, h: np.ndarray, noise_var: float) -> np.ndarray:
    """The regularised inverse ``(1 / h) max(0, 1 - a N / P)`` per rfft bin, capped at
    :data:`MAX_GAIN`: where the record's smoothed power ``P`` is within ``a`` times its white
    noise floor ``N`` (:data:`OVER_SUBTRACTION`: the smoothed periodogram of pure noise
    scatters by tens of per cent) the inverse is switched off, so it amplifies only the band
    the data support."""
    spec = np.abs(np.fft.rfft(y)) ** 2
    width = max(3, y.size // 400)
    power = ndimage.uniform_filter1d(spec, width, mode="nearest")
    floor = noise_var * y.size
    weight = np.clip(1.0 - OVER_SUBTRACTION * floor / np.maximum(power, 1e-300), 0.0, 1.0)
    inverse = 1.0 / h
    mag = np.abs(inverse)
    inverse = np.where(mag > MAX_GAIN, inverse * MAX_GAIN / np.maximum(mag, 1e-300), inverse)
    return inverse * weight


def record_noise_sigma(accel: np.ndarray, fs_hz: float) -> float:
    """The record's white-noise standard deviation from the top of its band.

    The median periodogram bin above :data:`NOISE_BAND` of Nyquist, over ``n ln 2`` (the
    median of a white-noise bin's exponential power): there the chain's low-pass or
    resonance has cut the motion, so what is left is the logger's noise. Where the motion
    still reaches up there the floor reads high, and the inverse only acts less.
    """
    y = np.asarray(accel, dtype=float) - float(np.mean(accel))
    power = np.abs(np.fft.rfft(y)) ** 2
    top = power[int(NOISE_BAND * (power.size - 1)) :]
    return float(np.sqrt(np.median(top) / (y.size * np.log(2.0))))


def inverse_noise_sigma(y: np.ndarray, fs_hz: float, chain: SensorChain, scatter: float) -> float:
    """Rule: the white-noise level a known chain's inverse is weighted by (:func:`wiener_gain`):
    the free flight's `scatter` of the record as recorded, or, behind a resonance the user's
    data sheet gives, the top of the band's floor (:func:`record_noise_sigma`) where that is
    lower.

    The scatter is the record's noise only where the record is a copy of the motion. A mount
    rings on through the flight after each impact (lightly damped: 0.01-0.1), and behind one
    within a few contact frequencies the scatter is that ringing: 0.89 g on a rig record
    without noise behind a mount at twice its contact's frequency. Weighted by it the inverse
    is off over much of the band it must restore, and the map of the half-undone pulses read
    beta 1.26 times the truth with an interval missing it, or refused it ("the contacts last
    3.6x the half period"); the top of the band, which the mount's roll-off has cleared of
    motion, holds the logger's noise alone. The lower of the two never weights the inverse
    above what the record shows. A low-pass alone does not ring through the flight, and there
    the scatter stands: the lower floor let its inverse lift more noise into the pulses, and
    damped contacts behind a 120 Hz 4th-order low-pass read 1-4 % further from the truth. A
    fitted chain keeps the scatter too: it is judged by the contact law its inverse leaves
    against the record as recorded (:data:`~.estimate.R2_SLACK`), a comparison set with it.
    So does a sheet fitted to recordings (:attr:`SensorChain.fitted_sheet`: a campaign's
    pooled chain), whose corners are profiled by the contact laws' R² read through this
    inverse: the lower floor lifts more noise into the pulses, the R² falls and flattens the
    profile, and a damped campaign's high-pass corner went from 4.07 Hz to 1.41 Hz (true 4.48).
    """
    if chain.source == "fitted" or chain.fitted_sheet or not chain.resonance_hz:
        return scatter
    return min(scatter, record_noise_sigma(y, fs_hz))


def deconvolve(y: np.ndarray, fs_hz: float, chain: SensorChain, noise_sigma: float) -> np.ndarray:
    """The record divided by the chain's resonance and low-pass, within the band it passes.

    Parameters
    ----------
    y : numpy.ndarray
        Recorded acceleration (treated as periodic: its ends are not used downstream).
    fs_hz : float
    chain : SensorChain
    noise_sigma : float
        Standard deviation of the record's white noise (the free flight's scatter).
    """
    if not chain.has_dynamics:
        return y
    freqs = np.fft.rfftfreq(y.size, 1.0 / fs_hz)
    gain = wiener_gain(y, chain_response(chain, freqs), noise_sigma**2)
    gain[0] = 1.0
    return np.fft.irfft(np.fft.rfft(y) * gain, y.size)


def identifiability(chain: SensorChain) -> str:
    """Rule: the one-line refusal where the low-pass does not pass the contact, else ''."""
    if chain.lowpass_hz and chain.contact_hz:
        if chain.lowpass_hz < MIN_LOWPASS_RATIO * chain.contact_hz:
            return (
                f"the low-pass at {chain.lowpass_hz:.0f} Hz is below the contact's frequency "
                f"{chain.contact_hz:.0f} Hz: beta is not identifiable from this sensor"
            )
    return ""


# --- the joint fit ----------------------------------------------------------------------


@dataclass
class _Windows:
    """The impacts' samples: residual force ``(n, length)``, each window's first sample, and
    each impact's core duration (samples)."""

    r: np.ndarray
    start: np.ndarray
    core: np.ndarray
    pre: int
    free_hz: float = 0.0
    plain_contact_hz: float = 0.0
    #: whether the plain map's law read a mount's ring rather than the contact
    ring_read: bool = False

    @property
    def n(self) -> int:
        return self.r.shape[0]

    @property
    def length(self) -> int:
        return self.r.shape[1]


def impact_windows(force: np.ndarray, core: np.ndarray, pre: int, post: int) -> _Windows:
    """Windows of `pre` samples before to `post` after each impact's first core sample, for the
    :data:`MAX_IMPACTS` largest impacts whose windows lie inside the record."""
    labels, n = ndimage.label(core)
    idx = np.arange(1, n + 1)
    first = np.array(ndimage.minimum(np.arange(force.size), labels, idx), dtype=int)
    size = np.array(ndimage.sum(core, labels, idx), dtype=float)
    peak = np.array(ndimage.maximum(force, labels, idx))
    ok = (first - pre >= 0) & (first + post < force.size)
    pick = np.flatnonzero(ok)[np.argsort(-peak[ok])[:MAX_IMPACTS]]
    pick = pick[np.argsort(first[pick])]
    starts = first[pick] - pre
    rows = starts[:, None] + np.arange(pre + post)[None, :]
    return _Windows(force[rows], starts, size[pick], pre)


def _unpack(theta, structure, fs_hz):
    """(chain, contact Hz, contact zeta) from the log parameters of a structure."""
    res, order = structure
    contact_hz, zeta = np.exp(theta[0]), np.exp(theta[1])
    k = 3
    fr = zr = fl = None
    if res:  # the resonance relative to the contact: a mount rings faster than the contact
        fr, zr = contact_hz * np.exp(theta[k]), np.exp(theta[k + 1])
        k += 2
    if order:
        fl = np.exp(theta[k])
    chain = SensorChain(resonance_hz=fr, resonance_damping=zr, lowpass_hz=fl,
                        lowpass_order=order or None)  # fmt: skip
    return chain, contact_hz, zeta


def _n_shape(structure) -> int:
    return 3 + 2 * bool(structure[0]) + bool(structure[1])


def contact_pulse(
    t: np.ndarray, contact_hz: float, zeta: float, offset: float = 0.0, free_hz: float = 0.0
) -> np.ndarray:
    """The Kelvin-Voigt contact force of unit impact velocity at times `t` (s): zero before
    the onset and after the force first returns to zero (the restraint never pulls).

    In contact ``d'' + 2 s d' + W^2 d = -k e + forcing``: the penetration oscillates from
    ``d(0) = 0``, ``d'(0) = 1`` about an equilibrium ``offset / W`` (the free spring's pull
    at the gap and the forcing, in units of the impact velocity over ``W``); the force is
    ``K d + 2 s d'`` with ``K = W^2 - k`` (``k`` from `free_hz`).
    """
    w = 2 * np.pi * contact_hz
    s = zeta * w
    wd = w * np.sqrt(max(1.0 - zeta**2, 1e-6))
    tt = np.maximum(t, 0.0)
    decay = np.exp(-s * tt)
    sin, cos = np.sin(wd * tt), np.cos(wd * tt)
    rho = offset / w
    d = rho * (1.0 - decay * (cos + s / wd * sin)) + decay * sin / wd
    v = rho * decay * sin * w**2 / wd + decay * (cos - s / wd * sin)
    f = (w**2 - (2 * np.pi * free_hz) ** 2) * d + 2 * s * v
    after = np.cumsum((f <= 0) & (tt > 0)) > 0
    return np.where((t >= 0) & ~after, f, 0.0)


def _residuals(theta, win: _Windows, fs_hz: float, structure) -> np.ndarray:
    """Residuals of the pulse model (onsets last in `theta`), each impact's size and linear
    baseline projected out (variable projection)."""
    return _projected(_pulse_table(theta, win, fs_hz, structure), theta[-win.n :], win)


def _pulse_table(theta, win: _Windows, fs_hz: float, structure) -> np.ndarray:
    """The pulse through the chain at :data:`OVERSAMPLE` times the record's rate: the shape's
    part of :func:`_residuals` (the onsets only shift where it is read)."""
    chain, contact_hz, zeta = _unpack(theta, structure, fs_hz)
    fine = fs_hz * OVERSAMPLE
    t = np.arange((win.length + 2) * OVERSAMPLE) / fine
    table = contact_pulse(t, contact_hz, zeta, theta[2], win.free_hz)
    sos = chain_sos(chain, fine)
    if sos is not None:
        table = signal.sosfilt(sos, table)
    return table


def _projected(table: np.ndarray, t0: np.ndarray, win: _Windows) -> np.ndarray:
    """The windows' residuals with the pulse `table` read from onsets `t0`, each impact's size,
    linear baseline and velocity step (:func:`_velocity_step`) projected out."""
    n, length = win.n, win.length
    pos = (np.arange(length)[None, :] - t0[:, None]) * OVERSAMPLE
    grid = np.arange(table.size)
    pulse = np.interp(pos, grid, table, left=0.0, right=table[-1])
    step = _velocity_step(table)
    velocity = np.interp(pos, grid, step, left=0.0, right=step[-1])
    u = np.broadcast_to(np.arange(length) / length - 0.5, (n, length))
    a = np.stack([pulse, np.ones((n, length)), u, velocity], axis=-1)
    ata = np.einsum("nli,nlj->nij", a, a) + 1e-12 * np.eye(a.shape[-1])
    coef = np.linalg.solve(ata, np.einsum("nli,nl->ni", a, win.r)[..., None])[..., 0]
    return (win.r - np.einsum("nli,ni->nl", a, coef)).ravel()


def _velocity_step(table: np.ndarray) -> np.ndarray:
    """The recorded pulse's running integral (fine-grid samples, in record samples): the
    velocity change an impact leaves, as the record's integrated velocity carries it.

    The windows are the free-flight law's residual, and that law's velocity term ``c v`` is
    fitted on every sample outside the contacts' cores, the filtered pulse's tail included:
    behind a low-pass it reads the free damping several times too large (0.386 for 0.039 on
    the independent rig behind 84.6 Hz order 4), and the residual then carries ``-dc v(t)``,
    whose jump through each impact is this integral times ``dc`` and the impact's size. Left
    out of the model, the contact's damping and a faster low-pass corner take it (that
    record: 96.9 Hz for 84.6 Hz, contact zeta 0.18 for an elastic one); each impact's own
    coefficient, projected out like its baseline, takes it instead.
    """
    return np.cumsum(table) / OVERSAMPLE


@dataclass
class _StructureFit:
    structure: tuple[bool, int]
    theta: np.ndarray
    sse: float
    bic: float
    cov: np.ndarray | None


def _slowest_contact(
    win: _Windows, fs_hz: float, fn_hz: float, structure: tuple[bool, int] = (False, 0)
) -> float:
    """Lowest contact frequency: a contact lasts about half its period (less when damped), so
    its half period is at most :data:`MAX_HALF_PERIODS` times the core seen above the noise
    (a chain only lengthens it), and at least :data:`PLAIN_CONTACT_FRACTION` of the contact
    frequency the record as recorded gives (a low-pass smears the pulse, so that map reads the
    contact softer, never much stiffer, than it is). Where that map read a mount's ring
    instead (:func:`_plain_law_read_a_ring`; it reads the contact stiffer) the resonance
    alone is free of that bound; a `structure` with a low-pass keeps it: there a slow
    contact, a resonance near the corner and a faster low-pass mimic the low-pass alone (a
    142 Hz mount, zeta 0.1, at 2 % noise read R139 + L141/1 over a 34 Hz contact, beta 49.9
    for 41.6, when freed too)."""
    slowest = fs_hz / (2 * MAX_HALF_PERIODS * max(float(np.median(win.core)), 1.0))
    if not (win.ring_read and structure == (True, 0)):
        slowest = max(slowest, PLAIN_CONTACT_FRACTION * win.plain_contact_hz)
    return max(1.05 * fn_hz, min(slowest, 0.2 * fs_hz))


def _bounds(win: _Windows, fs_hz: float, fn_hz: float, structure):
    nyq = 0.49 * fs_hz
    lo = [np.log(_slowest_contact(win, fs_hz, fn_hz, tuple(structure))), np.log(1e-3), -0.9]
    hi = [np.log(nyq), np.log(0.95), 0.5]
    if structure[0]:
        lo += [np.log(MIN_RESONANCE_RATIO), np.log(MIN_RESONANCE_DAMPING)]
        hi += [np.log(nyq / fn_hz), np.log(MAX_RESONANCE_DAMPING)]
    if structure[1]:
        lo += [np.log(0.5 * fn_hz)]
        hi += [np.log(nyq)]
    lo += [max(win.pre - 4.0, 0.0)] * win.n
    hi += [win.pre + 1.0] * win.n
    return np.array(lo), np.array(hi)


def _fit_structure(
    win: _Windows,
    fs_hz: float,
    fn_hz: float,
    structure,
    starts,
    max_nfev: int = MAX_NFEV,
    corner_hz: float | None = None,
) -> _StructureFit:
    """Least squares of one chain structure from each start; the best. With `corner_hz` the
    low-pass corner is held there (a profile point) and the rest fitted."""
    lower, upper = _bounds(win, fs_hz, fn_hz, structure)
    k, n = _n_shape(structure), win.n
    free = np.ones(k + n, dtype=bool)
    if corner_hz is not None:
        free[k - 1] = False

    def full(x: np.ndarray) -> np.ndarray:
        th = np.empty(k + n)
        th[free] = x
        if corner_hz is not None:
            th[k - 1] = np.log(corner_hz)
        return th

    # the last pulse table and the last residuals: an onsets' step reads the table again, and
    # the Jacobian is asked for where the last step was taken
    table: list = [None, None]
    last: list = [None, None]

    def resid(x: np.ndarray) -> np.ndarray:
        th = full(x)
        if table[0] is None or not np.array_equal(th[:k], table[0]):
            table[:] = [th[:k].copy(), _pulse_table(th, win, fs_hz, structure)]
        out = _projected(table[1], th[k:], win)
        last[:] = [x.copy(), out]
        return out

    def jac(x: np.ndarray) -> sparse.csr_array:
        f0 = last[1] if last[0] is not None and np.array_equal(x, last[0]) else resid(x)
        return _difference_jacobian(resid, x, f0, int(free[:k].sum()), win, lower[free],
                                    upper[free])  # fmt: skip

    best = None
    for start in starts:
        sol = optimize.least_squares(
            resid, np.clip(start, lower + 1e-9, upper - 1e-9)[free],
            bounds=(lower[free], upper[free]), x_scale="jac", max_nfev=max_nfev, jac=jac,
        )  # fmt: skip
        sol.x = full(sol.x)
        sse = float(np.sum(sol.fun**2))
        if best is None or sse < best[1]:
            best = (sol, sse)
    sol, sse = best
    m = win.r.size
    p = k + 5 * n  # the shape, and each impact's onset, size, linear baseline and step
    bic = m * np.log(max(sse, 1e-300) / m) + p * np.log(m)
    jac = sol.jac.toarray() if hasattr(sol.jac, "toarray") else np.asarray(sol.jac)
    cov = (
        None if corner_hz is not None else np.linalg.pinv(jac.T @ jac)[:k, :k] * sse / max(m - p, 1)
    )
    return _StructureFit(structure, sol.x, sse, float(bic), cov)


#: Relative step of the chain fit's forward differences.
DIFF_STEP = 1e-4


def _difference_jacobian(resid, x, f0, n_shape: int, win: _Windows, lo, hi) -> sparse.csr_array:
    """The forward-difference Jacobian of the pulse residuals at `x` (the free shape parameters,
    then one onset per impact), sparse.

    An impact's residuals depend on its own onset and on the shape, so each shape parameter is
    stepped alone and all onsets in one evaluation (which reads the shape's pulse table again).
    scipy's ``least_squares`` does the same from a ``jac_sparsity`` pattern with the same
    steps (:data:`DIFF_STEP` ``|x|``, ``sqrt(eps) max(1, |x|)`` where that is no step, reversed
    or shortened where a bound is in the way) and so builds the same matrix, but spends about a
    tenth of a chain fit finding and assembling the pattern's entries at every Jacobian.
    """
    sign = np.where(x >= 0, 1.0, -1.0)
    h = DIFF_STEP * sign * np.abs(x)
    h = np.where(
        (x + h) - x == 0, np.sqrt(np.finfo(float).eps) * sign * np.maximum(1.0, np.abs(x)), h
    )
    room_lo, room_hi = x - lo, hi - x
    fits = np.abs(h) <= np.maximum(room_lo, room_hi)
    h[((x + h < lo) | (x + h > hi)) & fits] *= -1
    up, down = (room_hi >= room_lo) & ~fits, (room_hi < room_lo) & ~fits
    h[up], h[down] = room_hi[up], -room_lo[down]
    m = f0.size
    vals = np.empty((m, n_shape + 1))
    for g, cols in enumerate([*([j] for j in range(n_shape)), np.arange(n_shape, x.size)]):
        step = x.copy()
        step[cols] += h[cols]
        dx = step - x
        df = resid(step) - f0
        # the onsets' column on each residual is its own impact's
        vals[:, g] = df / (dx[cols] if g < n_shape else np.repeat(dx[cols], win.length))
    indices = np.empty((m, n_shape + 1), dtype=np.int32)
    indices[:, :n_shape] = np.arange(n_shape)
    indices[:, n_shape] = n_shape + np.repeat(np.arange(win.n), win.length)
    indptr = np.arange(0, m * (n_shape + 1) + 1, n_shape + 1, dtype=np.int32)
    return sparse.csr_array((vals.ravel(), indices.ravel(), indptr), shape=(m, x.size))


def _grid_best(win: _Windows, fs_hz: float, structure, thetas: list[np.ndarray], i: int) -> float:
    """``exp(theta[i])`` of the candidate in `thetas` with the least squared residual (a
    global look at one parameter before the local least squares)."""
    sse = [float(np.sum(_residuals(th, win, fs_hz, structure) ** 2)) for th in thetas]
    return float(np.exp(thetas[int(np.argmin(sse))][i]))


def _theta(structure, contact, res, corner, timing: np.ndarray) -> np.ndarray:
    """Parameters of a structure: logs of the shape's frequencies and damping, then timing."""
    th = [np.log(contact[0]), np.log(contact[1]), contact[2]]
    if structure[0]:
        th += [np.log(max(res[0] / contact[0], MIN_RESONANCE_RATIO * 1.01)), np.log(res[1])]
    if structure[1]:
        th += [np.log(corner)]
    return np.r_[th, timing]


def _shape_of(fit: _StructureFit, fs_hz: float):
    """(contact (Hz, zeta, offset), resonance (Hz, zeta) or None, corner or None, timing)."""
    chain, contact_hz, zeta = _unpack(fit.theta, fit.structure, fs_hz)
    res = (chain.resonance_hz, chain.resonance_damping) if chain.resonance_hz else None
    timing = fit.theta[_n_shape(fit.structure) :]
    return (contact_hz, zeta, fit.theta[2]), res, chain.lowpass_hz, timing


def fit_chain(
    force: np.ndarray,
    core: np.ndarray,
    fs_hz: float,
    natural_frequency_hz: float,
    samples_per_contact: float,
    ring_hz: float | None = None,
    highpass_hz: float = 0.0,
    contact_hz: float | None = None,
    noise_sigma: float | None = None,
    profile: bool = True,
) -> SensorChain | None:
    """The sensor chain and the contact's poles, fitted jointly to every impact's pulse.

    Stage by stage (:class:`_ChainSearch`), each from the last one's contact: no chain; the
    resonance (from the post-impact ring, or a grid over contact and resonance); the
    second-order low-pass (from a grid over contact and corner: a low-pass near the contact's
    own frequency reads as a slower contact to the chain-free fit); both where the resonance
    paid; the other orders where a low-pass paid. :func:`_chosen_chain` picks.

    Parameters
    ----------
    force : numpy.ndarray
        Residual force of the free-flight law (compressive positive), the record's rate.
    core : numpy.ndarray
        Samples well inside a contact (beyond a few free-flight sigmas).
    fs_hz, natural_frequency_hz : float
    samples_per_contact : float
        Median core samples per impact (the contact's duration, smeared by the chain).
    ring_hz : float, optional
        A post-impact ringing frequency, the resonance's start.
    highpass_hz : float
        The high-pass corner found with the free-flight law (reported with the chain).
    contact_hz : float, optional
        The contact frequency of the plain map's law, a start beside the duration's.
    noise_sigma : float, optional
        The record's white-noise scatter: where the chain-free pulses fit down to
        :data:`NOISE_FLOOR` times its variance, no chain is fitted.
    profile : bool
        Profile the low-passes the impacts cannot exclude (``lowpass_not_excluded``, what
        beta's interval reads); False leaves it empty and the chain as it is.

    Returns
    -------
    SensorChain or None
        The structure of least BIC, its parameters and intervals (a stage kept only where it
        lowers the BIC by :data:`MIN_BIC_GAIN`); None with fewer than 3 usable impacts.
    """
    # a function of its inputs alone: kept where a caller evaluates the same records again
    # (:func:`~.kept_fits.fits_kept`, a measurement loop's iterations)
    inputs = (force, core, fs_hz, natural_frequency_hz, samples_per_contact, ring_hz,
              highpass_hz, contact_hz, noise_sigma, profile)  # fmt: skip
    return kept("chain", inputs, lambda: _fitted_chain(*inputs))


def _fitted_chain(
    force: np.ndarray,
    core: np.ndarray,
    fs_hz: float,
    natural_frequency_hz: float,
    samples_per_contact: float,
    ring_hz: float | None,
    highpass_hz: float,
    contact_hz: float | None,
    noise_sigma: float | None,
    profile: bool,
) -> SensorChain | None:
    """:func:`fit_chain`, fitted."""
    win = _chain_windows(force, core, fs_hz, natural_frequency_hz, samples_per_contact,
                         ring_hz, contact_hz)  # fmt: skip
    if win is None:
        return None
    # in the windows' own unit, so the fit and the noise test do not depend on the record's
    unit = force_unit(win.r)
    win.r = win.r / unit
    noise_sigma = None if noise_sigma is None else noise_sigma / unit
    search = _ChainSearch(win, fs_hz, natural_frequency_hz)
    none = search.no_chain(contact_hz)
    if not (noise_sigma and none.sse <= NOISE_FLOOR * win.r.size * noise_sigma**2):
        res = search.resonance(ring_hz)
        lp = search.lowpass()
        if res.bic < none.bic - MIN_BIC_GAIN:
            search.both(res, lp)
        search.other_orders(none)
    best = _best_fit(search.fits)
    chain = _chosen_chain(best, fs_hz, highpass_hz)
    if not profile:
        return chain
    return dataclasses.replace(chain, lowpass_not_excluded=search.lowpass_profile(best))


def _chain_windows(
    force: np.ndarray,
    core: np.ndarray,
    fs_hz: float,
    fn_hz: float,
    samples_per_contact: float,
    ring_hz: float | None,
    contact_hz: float | None,
) -> _Windows | None:
    """Rule: the impact windows the fit reads (half a contact before, the contact and a tail of
    1.5 contacts or 3 rings after), or None with fewer than 3 impacts."""
    labels, n_core = ndimage.label(core)
    if n_core < 3:
        return None
    # the core's own runs: the map's impacts merge a ring's lobes into one
    spc = float(np.median(ndimage.sum(core, labels, np.arange(1, n_core + 1))))
    spc = max(min(spc, float(samples_per_contact)), 1.0)
    pre = int(max(3, np.ceil(0.5 * spc)))
    tail = int(max(8, np.ceil(1.5 * spc)))
    if ring_hz:
        tail = max(tail, int(np.ceil(3 * fs_hz / ring_hz)))
    win = impact_windows(force, core, pre, int(np.ceil(spc)) + tail)
    if win.n < 3:
        return None
    win.free_hz = fn_hz
    win.plain_contact_hz = float(contact_hz or 0.0)
    win.ring_read = _plain_law_read_a_ring(contact_hz, samples_per_contact, fs_hz)
    return win


def _plain_law_read_a_ring(contact_hz: float | None, spc: float, fs_hz: float) -> bool:
    """Rule: whether the plain map's contact frequency is a mount's ring's, not the contact's:
    a contact lasts about half its period, and an impact whose core lasts `spc` samples, more
    than :data:`PLAIN_RING_HALF_PERIODS` half periods of the plain law, was not read by it."""
    return bool(contact_hz) and spc * 2.0 * contact_hz / fs_hz > PLAIN_RING_HALF_PERIODS


class _ChainSearch:
    """The stages of :func:`fit_chain`: each fits one chain structure from starts its own
    grid picks, and keeps it in :attr:`fits`."""

    def __init__(self, win: _Windows, fs_hz: float, fn_hz: float):
        self.win, self.fs, self.fn = win, fs_hz, fn_hz
        self.cap = 0.45 * fs_hz
        self.timing = np.full(win.n, win.pre - 0.5)
        self.grid = np.geomspace(1.01 * _slowest_contact(win, fs_hz, fn_hz), 0.4 * fs_hz, GRID)
        self.resonance_grid = np.geomspace(
            1.01 * _slowest_contact(win, fs_hz, fn_hz, (True, 0)), 0.4 * fs_hz, GRID
        )
        self.fits: dict[tuple[bool, int], _StructureFit] = {}
        self.contact: tuple = ()
        self.tm = self.timing

    def run(self, structure, starts) -> _StructureFit:
        self.fits[structure] = _fit_structure(self.win, self.fs, self.fn, structure, starts)
        return self.fits[structure]

    def _sse(self, structure, theta) -> float:
        return float(np.sum(_residuals(theta, self.win, self.fs, structure) ** 2))

    def no_chain(self, contact_hz: float | None) -> _StructureFit:
        """The contact alone, from the best of a grid of contact frequencies (and the plain
        map's); its contact and timing start the later stages."""
        st = (False, 0)
        hint = [float(np.clip(contact_hz, 1.2 * self.fn, 0.4 * self.fs))] if contact_hz else []
        thetas = [_theta(st, (c, 0.1, 0.0), None, None, self.timing) for c in self.grid]
        c_best = _grid_best(self.win, self.fs, st, thetas, 0)
        fit = self.run(st, [_theta(st, (c, 0.1, 0.0), None, None, self.timing)
                            for c in {c_best, *hint}])  # fmt: skip
        self.contact, _, _, self.tm = _shape_of(fit, self.fs)
        return fit

    def resonance(self, ring_hz: float | None) -> _StructureFit:
        """The mount's resonance: a ring that dominates the pulse misleads the chain-free
        contact, so the start is a grid over both (and the post-impact ring)."""
        st, fn, cap, contact = (True, 0), self.fn, self.cap, self.contact
        pairs = [(c, f) for c in {*self.resonance_grid, contact[0]}
                 for f in np.geomspace(2 * fn, cap, GRID)
                 if f >= 1.05 * MIN_RESONANCE_RATIO * c]  # fmt: skip
        sse = [self._sse(st, _theta(st, (c, 0.1, 0.0), (f, 0.05), None, self.timing))
               for c, f in pairs]  # fmt: skip
        c_best, r_best = pairs[int(np.argmin(sse))]
        res_starts = {r_best} | ({ring_hz} if ring_hz and ring_hz < cap else set())
        starts = [(c_best, r_best, self.timing), *[(contact[0], f, self.tm) for f in res_starts]]
        thetas = [_theta(st, (c, 0.1, 0.0), (f, z), None, t) for c, f, t in starts
                  for z in (0.02, 0.08) if f >= 1.05 * MIN_RESONANCE_RATIO * c]  # fmt: skip
        return self.run(st, thetas)

    def lowpass(self) -> _StructureFit:
        """The second-order low-pass: from the chain-free contact with a grid of corners, and
        from the best of a grid over contact and corner (a corner near the contact's frequency
        makes the chain-free fit read a slower contact, which a corner grid alone keeps)."""
        st, contact, cap = (False, 2), self.contact, self.cap
        corners = np.geomspace(0.5 * contact[0], cap, GRID)
        thetas = [_theta(st, contact, None, f, self.tm) for f in corners]
        l_best = _grid_best(self.win, self.fs, st, thetas, 3)
        pairs = [(c, f) for c in {*self.grid, contact[0]}
                 for f in np.geomspace(max(0.5 * c, 0.5 * self.fn), cap, GRID)]  # fmt: skip
        sse = [self._sse(st, _theta(st, (c, 0.1, 0.0), None, f, self.timing)) for c, f in pairs]
        c_best, f_best = pairs[int(np.argmin(sse))]
        starts = [_theta(st, contact, None, l_best, self.tm),
                  _theta(st, (c_best, 0.1, 0.0), None, f_best, self.timing)]  # fmt: skip
        return self.run(st, starts)

    def both(self, res: _StructureFit, lp: _StructureFit) -> _StructureFit:
        """Resonance and second-order low-pass, from the resonance's fit and the low-pass's
        corner (or the best of a grid of corners)."""
        st = (True, 2)
        c_r, r_r, _, t_r = _shape_of(res, self.fs)
        corner = _shape_of(lp, self.fs)[2]
        corners = np.geomspace(0.5 * self.contact[0], self.cap, GRID)
        thetas = [_theta(st, c_r, r_r, f, t_r) for f in corners]
        l_best = _grid_best(self.win, self.fs, st, thetas, 5)
        return self.run(st, [_theta(st, c_r, r_r, c, t_r) for c in {l_best, corner}])

    def lowpass_profile(self, best: _StructureFit) -> tuple[tuple[int, float], ...]:
        """Per order of :data:`PROFILE_ORDERS`, the lowest corner (of :data:`PROFILE_CORNERS`
        times the contact frequency, walking down) at which the chosen structure with that
        low-pass fits the impacts as well as the chosen one: its squared residual within the
        :data:`COVERAGE` quantile of chi-square (1 degree) times the residual variance.

        A low-pass at a few contact frequencies barely changes the pulse's shape (its delay
        goes into the onsets), so the fit rarely sees it, yet its phase bends the map: on the
        independent rig a 3rd-order 145 Hz low-pass under a 28 Hz contact reads beta 8.3 for
        7.8. Where the impacts cannot exclude such a low-pass, the reading through it belongs
        in beta's interval."""
        contact, res, corner, timing = _shape_of(best, self.fs)
        # the model's misfit is smooth, so neighbouring residuals are not independent: one
        # independent sample per core duration of each window
        m = self.win.n * self.win.length / max(float(np.median(self.win.core)), 1.0)
        allowed = best.sse * (1.0 + stats.chi2.ppf(COVERAGE, 1) / max(m - 3.0, 1.0))
        out = []
        for order in PROFILE_ORDERS:
            st = (best.structure[0], order)
            lowest = None
            # from the fastest corner down, to the first that fits worse: without a fitted
            # low-pass a faster corner changes the pulse less, so the corners that fit form a
            # run from the top (and a record that excludes the fastest costs one fit)
            for f in PROFILE_CORNERS[::-1] * contact[0]:
                if f >= self.cap or (corner and order == best.structure[1] and f >= corner):
                    continue
                fit = _fit_structure(self.win, self.fs, self.fn, st,
                                     [_theta(st, contact, res, f, timing)], PROFILE_NFEV,
                                     corner_hz=f)  # fmt: skip
                if fit.sse <= allowed:
                    lowest = float(f)
                elif lowest is not None or not corner:
                    break
            if lowest is not None:
                out.append((order, lowest))
        return tuple(out)

    def other_orders(self, none: _StructureFit) -> None:
        """Orders 1, 3 and 4 of each second-order low-pass structure (with and without the
        resonance) that paid over the chain-free fit: a steeper low-pass may beat a resonance
        the second order did not (a resonance mimics a low-pass's ring within the window)."""
        for second in [f for f in self.fits.values() if f.structure[1] == 2]:
            if not second.bic < none.bic - MIN_BIC_GAIN:
                continue
            c_b, r_b, corner, t_b = _shape_of(second, self.fs)
            for order in (o for o in ORDERS if o != 2):
                st = (second.structure[0], order)
                self.run(st, [_theta(st, c_b, r_b, min(f * corner, self.cap), t_b)
                              for f in (0.85, 1.2)])  # fmt: skip


def _best_fit(fits) -> _StructureFit:
    """Rule: the structure of least BIC, a stage kept only where it gains :data:`MIN_BIC_GAIN`
    and leaves :data:`STAGE_GAIN` of the simpler structure's squared residual."""
    ranked = sorted(fits.values(), key=lambda f: (_n_shape(f.structure), f.structure[1]))
    best = ranked[0]
    for f in ranked[1:]:
        more = _n_shape(f.structure) > _n_shape(best.structure)
        if f.sse < (STAGE_GAIN if more else 1.0) * best.sse and f.bic < best.bic - MIN_BIC_GAIN:
            best = f
    return best


def _chosen_chain(best: _StructureFit, fs_hz: float, highpass_hz: float) -> SensorChain:
    """The chain of the chosen fit with its intervals; a corner or resonance at or above
    :data:`MAX_CORNER_FRACTION` fs is reported as none."""
    chain, contact_hz, zeta = _unpack(best.theta, best.structure, fs_hz)
    z = float(stats.norm.ppf(0.5 + COVERAGE / 2))
    names = ["contact_hz", "contact_damping", "offset"]
    if best.structure[0]:
        names += ["resonance_hz", "resonance_damping"]
    if best.structure[1]:
        names += ["lowpass_hz"]
    intervals = {}
    for i, name in enumerate(names):
        if name == "offset" or best.cov is None:
            continue
        if name == "resonance_hz":  # log f_r = log(contact) + log(ratio): both variances
            var = best.cov[0, 0] + best.cov[i, i] + 2 * best.cov[0, i]
            v = float(best.theta[0] + best.theta[i])
        else:
            var, v = best.cov[i, i], float(best.theta[i])
        se = float(np.sqrt(max(var, 0.0)))
        with np.errstate(over="ignore"):
            ends = [float(np.exp(v - z * se)), float(np.exp(v + z * se))]
        if all(np.isfinite(ends)):  # an unbounded one is not reported (JSON has no inf)
            intervals[name] = ends
    cap = MAX_CORNER_FRACTION * fs_hz
    fr = chain.resonance_hz if chain.resonance_hz and chain.resonance_hz < cap else None
    fl = chain.lowpass_hz if chain.lowpass_hz and chain.lowpass_hz < cap else None
    return SensorChain(
        resonance_hz=fr,
        resonance_damping=chain.resonance_damping if fr else None,
        lowpass_hz=fl,
        lowpass_order=chain.lowpass_order if fl else None,
        highpass_hz=highpass_hz,
        source="fitted",
        intervals=intervals,
        contact_hz=contact_hz,
        contact_damping=zeta,
    )


def identify_sensor_chain(
    accel: np.ndarray,
    fs_hz: float,
    natural_frequency_hz: float,
    forcing_frequency_hz: float | None = None,
    max_periods: float | None = 24.0,
) -> SensorChain | None:
    """The accelerometer chain of one recording, identified from its impacts.

    The restoring-force estimate's own identification
    (:func:`~stiffnet.restoring_force.restoring_force_estimate` with no data sheet) on at most
    `max_periods` forcing periods, for callers that want the chain alone: ``diagnose``'s
    starting point for ``sensor_dynamics`` and its evidence. None where the record shows no
    impacts to fit (or cannot be read at all).
    """
    from stiffnet.errors import StiffnetError
    from stiffnet.restoring_force.estimate import restoring_force_estimate

    try:
        r = restoring_force_estimate(
            accel, fs_hz, natural_frequency_hz=natural_frequency_hz,
            forcing_frequency_hz=forcing_frequency_hz, max_periods=max_periods,
        )  # fmt: skip
    except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None
    return r.sensor


def shared_chain(chains: list[dict | None]) -> dict[str, Any] | None:
    """The chain a campaign's recordings share (one sensor): per stage, the median over the
    recordings that show it, where at least half of the identified ones do; None without
    any identified chain. Input: :meth:`SensorChain.to_dict` per recording (None: unread)."""
    seen = [c for c in chains if c]
    if not seen:
        return None
    out: dict[str, Any] = {"n": len(seen)}
    for key, partner in (("resonance_hz", "resonance_damping"), ("lowpass_hz", "lowpass_order"),
                         ("highpass_hz", None)):  # fmt: skip
        values = [c for c in seen if c.get(key)]
        if 2 * len(values) < len(seen):
            out[key] = None
            continue
        out[key] = float(np.median([c[key] for c in values]))
        out[f"{key}_range"] = [float(v) for v in np.quantile([c[key] for c in values], [0.1, 0.9])]
        if partner:
            out[partner] = float(np.median([c[partner] for c in values]))
    return out


def shared_chain_sheet(shared: dict[str, Any] | None) -> dict[str, float] | None:
    """The chain a campaign's recordings share (:func:`shared_chain`) as a data sheet
    (:data:`SENSOR_KEYS`); None without a resonance or low-pass (nothing to undo that a
    recording's own high-pass fit would not find)."""
    if not shared or not (shared.get("resonance_hz") or shared.get("lowpass_hz")):
        return None
    sheet = {k: float(shared.get(k) or 0.0) for k in SENSOR_KEYS}
    if sheet["lowpass_order"]:
        sheet["lowpass_order"] = float(max(1, round(sheet["lowpass_order"])))
    return sheet


#: A chain shared by a campaign's recordings (:func:`shared_chain`) is theirs when, undone on
#: them, the median R² their contact laws lose against their own readings is at most this
#: (:func:`shared_chain_shortfall`). Measured (contact laws of 6 s records): 0.000 and -0.001
#: on the bench campaign (one 237 Hz resonance; 24 and 8 recordings), 0.018 on an
#: independent-rig campaign whose shared low-pass is 13 % off, 0.005 on a rig campaign at
#: three sampling rates; 0.485 where the shared chain took a 45 Hz low-pass the sensor
#: lacks (its recordings refused or read at R² 0.5 through it, 0.99 through their own).
CHAIN_CONFIRMED_SHORTFALL = 0.05


def shared_chain_shortfall(own: list[dict | None], shared: list[dict | None]) -> float | None:
    """Median R² the recordings' contact laws lose when read through a campaign's shared
    chain instead of as they were read alone (each a restoring-force result with
    ``contact_r2``); None without any.

    A reading refused after its contact law was fitted (contacts longer than the law allows,
    a law under half the force) still counts its law's R²: the chain that reads the pulse
    closer to a contact law is the better one, refused or not. A reading without a contact
    law (missing, no impact, a refusal before the law) explains nothing (R² 0)."""
    if not own:
        return None
    lost = [_law_r2(o) - _law_r2(s) for o, s in zip(own, shared, strict=True)]
    return float(np.median(lost))


def _law_r2(reading: dict | None) -> float:
    """The R² of the contact law that read a result's beta: its Hunt-Crossley law's where it
    fitted one (a campaign read with its contacts' dissipation: the library's law it was
    fitted beside misses the dissipation), else ``contact_r2``; 0 without a law."""
    hc = (reading or {}).get("hunt_crossley") or {}
    r2 = hc.get("r2") if isinstance(hc, dict) else None
    if r2 is not None and np.isfinite(r2):
        return float(r2)
    return float((reading or {}).get("contact_r2") or 0.0)
