"""The measurement chain: accelerometer mounted resonance, charge amplifier, anti-alias filter.

The paper's rig measures the mass's acceleration with an accelerometer whose
signal goes through a charge amplifier with high/low-pass filters before a
LabVIEW acquisition card (section 2, Fig. 1b). None of that is in eqs 11-12;
this effect adds its linear dynamics to the sampled acceleration.
"""

from __future__ import annotations

import functools
from dataclasses import replace
from typing import ClassVar

import numpy as np
from scipy import signal as sps

from stiffnet.effects.base import (
    EffectParams,
    MeasurementEffect,
    ParamArrays,
    ParamValue,
    batch_signal,
    param,
    per_row,
)
from stiffnet.effects.fit_space import FitParam, FitSpace

_MAX_CORNER_FRACTION = 0.45
"""Corners at or above this fraction of the sampling rate are skipped (see SensorDynamics)."""


def resonance_sos(resonance_hz: float, damping: float, fs_hz: float) -> np.ndarray:
    """Digital second-order sections of ``w_r^2 / (s^2 + 2 zeta_r w_r s + w_r^2)``.

    Bilinear transform with the frequency prewarped so that the digital
    resonance lies exactly at ``resonance_hz``; the DC gain is exactly 1.

    Parameters
    ----------
    resonance_hz : float
        Mounted resonance frequency f_r in Hz, below ``fs_hz / 2``.
    damping : float
        Damping ratio zeta_r of the resonance.
    fs_hz : float
        Sampling rate in Hz.

    Returns
    -------
    numpy.ndarray
        SOS array of shape ``(1, 6)``.
    """
    # prewarp: the bilinear map sends analog w_a to digital 2 fs atan(w_a / (2 fs))
    w = 2.0 * fs_hz * np.tan(np.pi * resonance_hz / fs_hz)
    poles = np.roots([1.0, 2.0 * damping * w, w * w])
    z, p, k = sps.bilinear_zpk([], poles, w * w, fs_hz)
    return sps.zpk2sos(z, p, k)


def _steady_state(sos: np.ndarray) -> np.ndarray:
    """``scipy.signal.sosfilt_zi`` of a read-only design from :meth:`SensorDynamics._design`,
    kept with it (the same design, the same numbers)."""
    return _steady_state_of(sos.tobytes(), sos.shape)


@functools.lru_cache(maxsize=4096)
def _steady_state_of(data: bytes, shape: tuple[int, ...]) -> np.ndarray:
    zi = sps.sosfilt_zi(np.frombuffer(data).reshape(shape))
    zi.setflags(write=False)
    return zi


class SensorDynamics(MeasurementEffect):
    r"""Linear dynamics of the accelerometer and its conditioning electronics.

    The recorded acceleration is the true one passed, causally, through three
    stages in the order the hardware applies them:

    1. **Mounted accelerometer resonance** (seismic mass on the piezo stack,
       stiffened or softened by the stud/magnet/wax mount)::

           H_r(s) = w_r^2 / (s^2 + 2 zeta_r w_r s + w_r^2),   w_r = 2 pi f_r

       unity gain well below f_r, lightly damped (zeta_r ~ 0.01-0.05 for
       piezoelectric sensors). Every sharp impact spike excites it, so the
       signal *rings* at f_r after each impact, decaying as
       ``exp(-zeta_r w_r t)``. Stud-mounted industrial accelerometers resonate
       at 20-50 kHz, magnet-mounted ones at 1-10 kHz, wax/adhesive or heavy
       sensors on a light mass lower; the default 1.5 kHz stands for a magnet
       mount, low enough to matter at the few-kHz rates used for a ~10 Hz rig.

    2. **Charge-amplifier high-pass** (the feedback resistor across the
       charge capacitor), first order::

           H_h(s) = s / (s + w_h),   w_h = 2 pi f_h

       It removes DC offsets (sensor bias, gravity component, drift) and adds
       a phase lead at low frequency. Laboratory charge amplifiers offer
       0.1-10 Hz lower corners; default 1 Hz. ``highpass_hz = 0`` disables it.

    3. **Anti-alias low-pass** of the conditioning amplifier / acquisition
       card, Butterworth of order ``lowpass_order`` at ``lowpass_hz`` (default
       1 kHz, second order). It rounds and lowers the impact spikes and delays
       them slightly. ``lowpass_hz = 0`` disables it.

    Each stage is discretised at the row's sampling rate by the bilinear
    transform with prewarping (the resonance and the filter corners land
    exactly at their nominal frequencies) and applied with ``sosfilt``:
    causal, like real hardware, not zero-phase. The filter states start in the
    steady state for a constant input equal to the first sample, i.e. the
    chain had been running before the record began: a DC level produces no
    start-up transient. A non-zero slope at the first sample still excites a
    small start-up ring of amplitude about ``x'(0) / w_r``; a
    caller that needs a clean start simulates a short lead-in (a few
    ``1 / (zeta_r w_r)``) and drops it after the measurement effects.

    Notes
    -----
    Simplifications:

    * The filters act on the already sampled signal, so the low-pass shapes
      the in-band response (spike height, delay) but cannot undo aliasing of
      content above Nyquist the way an analog anti-alias filter would.
    * A stage whose frequency is at or above 0.45 fs is skipped: a resonance
      there cannot ring at that sampling rate (its bilinear image would be
      squeezed against Nyquist), and a corner there barely touches the band.

    Parameters are per trajectory; ``lowpass_order`` is rounded to an integer.
    """

    name = "sensor_dynamics"
    #: Analog hardware: a campaign's comparison simulates the motion faster than the logger's
    #: rate, filters it, then samples it (stiffnet.campaign.simulate.oversampling).
    analog = True
    #: Training-world prior (docs/priors.md): resonance relative to f_n, anti-alias
    #: corner relative to fs; what labs have: a heavy or wax-mounted sensor on a light mass
    #: rings a few f_n up, charge amplifiers offer 0.1-10 Hz lower corners, conditioning
    #: amplifiers low-pass down to 0.05 fs.
    prior: ClassVar[dict | None] = {
        "probability": 0.7,
        "params": {"resonance_damping": [0.01, 0.1], "highpass_hz": [0.0, 5.0],
                   "lowpass_order": [1.0, 4.0]},
        "relative": {
            "resonance_hz": {"per": "natural_frequency", "range": [6.0, 300.0]},
            "lowpass_hz": {"per": "sampling_rate", "range": [0.05, 0.45]},
        },
    }  # fmt: skip
    order = 10

    class Params(EffectParams):
        resonance_hz: ParamValue = param(
            1500.0, 50.0, 50000.0, "mounted resonance frequency of the accelerometer", "Hz"
        )
        resonance_damping: ParamValue = param(
            0.03, 0.001, 1.0, "damping ratio of the accelerometer resonance", ""
        )
        highpass_hz: ParamValue = param(
            1.0, 0.0, 100.0, "charge-amplifier high-pass corner (first order; 0 disables)", "Hz"
        )
        lowpass_hz: ParamValue = param(
            1000.0, 0.0, 100000.0, "anti-alias low-pass corner (Butterworth; 0 disables)", "Hz"
        )
        lowpass_order: ParamValue = param(
            2.0,
            1,
            8,
            "order of the Butterworth low-pass (rounded to an integer)",
            "",
            integer=True,
        )

    #: The mounted resonance and the charge amplifier's high-pass corner (0: none); the
    #: low-pass is off (it shapes the band the resonance rings in far less than the
    #: resonance itself).
    fit_space = FitSpace(
        (
            FitParam("resonance_hz", 50.0, 1000.0, log=True),
            FitParam("resonance_damping", 0.01, 0.3, log=True),
            # linear down to 0: a rig with no high-pass (an assumed 1 Hz one left the
            # impact-aligned waveform of a rig without one 0.4-0.9 tolerances off)
            FitParam("highpass_hz", 0.0, 2.0),
        ),
        fixed={"lowpass_hz": 0.0, "lowpass_order": 2.0},
        multimodal=("resonance_hz",),
    )

    @classmethod
    def campaign_fit_space(cls, fs_hz_min: float) -> FitSpace:
        """The resonance searched up to the campaign's lowest ``0.45 fs`` (above, it is skipped)."""
        res, *others = cls.fit_space.free
        top = max(60.0, _MAX_CORNER_FRACTION * fs_hz_min)
        return replace(cls.fit_space, free=(replace(res, high=top), *others))

    @classmethod
    def observed_fit_space(cls, space: FitSpace, observed: dict[str, float]) -> FitSpace:
        """With an identified low-pass (``sensor_lowpass_hz``, ``sensor_lowpass_order``), its
        corner is searched from half of it up to the resonance's top (where the stage is
        skipped: no low-pass) at its identified order; without one, the space is unchanged."""
        f_l = observed.get("sensor_lowpass_hz")
        res, *_ = space.free
        if not f_l or not 0.5 * f_l < res.high:
            return space
        order = float(np.clip(np.rint(observed.get("sensor_lowpass_order", 2.0)), 1, 8))
        corner = FitParam("lowpass_hz", 0.5 * f_l, res.high, log=True)
        fixed = {k: v for k, v in space.fixed.items() if k != "lowpass_hz"}
        return replace(space, free=(*space.free, corner), fixed={**fixed, "lowpass_order": order})

    @classmethod
    def fit_seeds(cls, observed: dict[str, float], space: FitSpace) -> list[dict[str, float]]:
        """Start at the chain identified from the contact pulses (``sensor_<parameter>``; a
        stage it lacks: no high-pass, a resonance at the top of the search, i.e. none), then
        at the measured post-impact ringing frequency: the resonance's basin is a few per
        cent wide (the ringing is a few samples per cycle), a grid alone misses it."""
        res, damp = space.free[:2]
        # an identified low-pass (a free corner, :meth:`observed_fit_space`) in every seed
        lowpass = (
            {"lowpass_hz": observed["sensor_lowpass_hz"]} if "lowpass_hz" in space.names else {}
        )
        seeds = []
        if any(k.startswith("sensor_") for k in observed):
            f_r = observed.get("sensor_resonance_hz", res.high)
            seeds.append({
                **space.fixed, **lowpass,
                "resonance_hz": float(np.clip(f_r, res.low, res.high)),
                "resonance_damping": float(np.clip(observed.get("sensor_resonance_damping", 0.03),
                                                   damp.low, damp.high)),
                **({"highpass_hz": observed.get("sensor_highpass_hz", 0.0)}
                   if "highpass_hz" in space.names else {}),
            })  # fmt: skip
        f = observed.get("ringing_hz")
        if f is None or not np.isfinite(f):
            return seeds
        # with and without a charge-amplifier high-pass (when the space fits its corner)
        corners = (0.0, 1.0) if "highpass_hz" in space.names else (None,)
        return seeds + [
            {
                **space.fixed,
                **lowpass,
                "resonance_hz": float(np.clip(f * scale, res.low, res.high)),
                "resonance_damping": float(np.clip(zeta, damp.low, damp.high)),
                **({} if hp is None else {"highpass_hz": hp}),
            }
            for scale in (0.98, 1.0, 1.02)
            for zeta in (0.01, 0.03, 0.1)
            for hp in corners
        ]

    def apply(
        self, signal: np.ndarray, fs_hz: np.ndarray, p: ParamArrays, rng: np.random.Generator
    ) -> np.ndarray:
        """Pass each row through the sensor chain designed at that row's sampling rate.

        Parameters
        ----------
        signal : numpy.ndarray
            Accelerations, shape ``(B, N)``, model units.
        fs_hz : numpy.ndarray
            Sampling rate of each row in Hz, shape ``(B,)``.
        p : dict of numpy.ndarray
            Per-row parameters (see :class:`SensorDynamics.Params`), each ``(B,)``; the
            context ``"_row_samples"``, when given, is the samples each row needs: the chain
            is causal, so it filters no further and a row's later samples are left as they
            are (the samples it filters are the same, bit for bit).
        rng : numpy.random.Generator
            Unused (the chain is deterministic).

        Returns
        -------
        numpy.ndarray
            Filtered signal, a new ``(B, N)`` float64 array.
        """
        x = batch_signal(signal)
        b, n = x.shape
        out = x.copy()
        if b == 0 or n == 0:
            return out
        keys = ("resonance_hz", "resonance_damping", "highpass_hz", "lowpass_hz", "lowpass_order")
        table = np.column_stack(
            [np.broadcast_to(np.asarray(fs_hz, dtype=np.float64), (b,))]
            + [per_row(p, k, b) for k in keys]
        )
        table[:, -1] = np.rint(table[:, -1])
        # rows sharing a design (the common case: fixed parameters, one fs) filter together
        designs, which = np.unique(table, axis=0, return_inverse=True)
        need = p.get("_row_samples")
        for i, row in enumerate(designs):
            kept = self._design(*row)
            if kept is None:
                continue
            sos = kept.copy()  # scipy's sosfilt takes a writable design only
            rows = np.flatnonzero(which.ravel() == i)
            # rows of one design share their rate, so mostly their length too
            m = n if need is None else int(min(n, np.max(np.asarray(need)[rows])))
            zi = _steady_state(kept)[:, None, :] * x[rows, 0][None, :, None]
            out[rows, :m], _ = sps.sosfilt(sos, x[rows, :m], axis=-1, zi=zi)
        return out

    @staticmethod
    @functools.lru_cache(maxsize=4096)
    def _design(
        fs: float, f_r: float, zeta: float, f_h: float, f_l: float, order: float
    ) -> np.ndarray | None:
        """SOS of the whole chain at rate ``fs``, or None when every stage is skipped.

        Kept per parameters (read-only): a fit filters every evaluation's rows with the
        same few designs, and designing them (scipy's zpk2sos) cost as much as filtering."""
        if not fs > 0:
            raise ValueError(f"sampling rate must be positive, got {fs}")
        limit = _MAX_CORNER_FRACTION * fs
        stages = []
        if f_r < limit:
            stages.append(resonance_sos(f_r, zeta, fs))
        if 0 < f_h < limit:
            stages.append(sps.butter(1, f_h, "highpass", fs=fs, output="sos"))
        if 0 < f_l < limit:
            stages.append(sps.butter(int(order), f_l, "lowpass", fs=fs, output="sos"))
        if not stages:
            return None
        sos = np.vstack(stages)
        sos.setflags(write=False)
        return sos
