"""The record the learned model reads: the identified sensor chain undone (numpy/scipy only).

The restoring-force cross-check identifies the accelerometer's chain from the impacts, or
takes the user's data sheet (:mod:`serving.restoring_force_check`, ``sensor``). The learned
model was trained behind chains drawn from narrow priors (its card's ``data.priors``): a
record behind a chain outside them is outside its world, while the same record with the
chain divided out (:func:`stiffnet.restoring_force.chain.deconvolve`, within the band the
record supports) is closer to it. :func:`model_record` gives the record the model reads:

* ``"off"``: the record as recorded;
* ``"chain"``: every resonance, low-pass and high-pass the check applied, divided out;
* ``"resonance"``: the mount resonance alone;
* ``"outside_priors"``: only the stages that lie outside the model's sensor priors (a
  resonance below its lowest multiple of f_n, a low-pass below its lowest fraction of fs, a
  high-pass above its highest corner);
  a stage inside them is one the model has seen, and dividing it out only amplifies noise.

A fitted chain the check did not apply (its inverse left the contact law worse) is no
evidence of a chain and is never undone. The charge amplifier's 1st-order high-pass is
undone with the rest (``"chain"``; ``"outside_priors"``: only a corner above the prior's
highest): its inverse ``(s + w_h) / s`` adds ``w_h`` times the record's integral, the
velocity, whose unknown start and drift are taken away (:func:`highpass_undone`). Left in,
a corner of a few Hz turns the phase of the motion at f_n (23 degrees at 4 Hz for 9.5 Hz),
and the model reads that as stiffness: on the independent rig a record through a 3.6-4.5 Hz
high-pass alone reads beta 19-55 % off, and the same chain with its high-pass undone reads
what the record without any chain reads (docs/model_benchmark.md, "The high-pass the undo
left in"). The model's own prior (0-2 Hz) is no reason to leave one in: it reads beta
4-14 % off already behind 2 Hz, 0-6 % behind 1 Hz (against the same record without any
chain).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from scipy import integrate, signal

from serving.restoring_force_check import PRIOR_SLACK, sensor_prior_lows
from stiffnet.restoring_force.chain import (
    MIN_LOWPASS_RATIO,
    SensorChain,
    deconvolve,
    record_noise_sigma,
)

#: What the model may read (see the module's docstring).
UNDO_MODES = ("off", "chain", "resonance", "outside_priors")
#: Samples reflected at each end before the inverse (the FFT treats the record as periodic:
#: without them the end of the record leaks into its start through the inverse's response).
PAD_FRACTION = 0.05


def chain_to_undo(
    sensor: dict | None,
    priors: dict | None,
    fs_hz: float,
    natural_frequency_hz: float,
    mode: str,
) -> SensorChain | None:
    """The resonance, low-pass and high-pass to divide out of the record (None: nothing to
    undo).

    Parameters
    ----------
    sensor : dict or None
        The check's ``sensor`` (:meth:`~stiffnet.restoring_force.chain.SensorChain.to_dict`).
    priors : dict or None
        The model card's ``data.priors``.
    fs_hz, natural_frequency_hz : float
    mode : str
        One of :data:`UNDO_MODES`.
    """
    if mode not in UNDO_MODES:
        raise ValueError(f"undo mode must be one of {', '.join(UNDO_MODES)}, got {mode!r}")
    if mode == "off" or not sensor or sensor.get("applied") is False:
        return None
    fr, zr = sensor.get("resonance_hz"), sensor.get("resonance_damping")
    fl, order = sensor.get("lowpass_hz"), sensor.get("lowpass_order")
    fh = float(sensor.get("highpass_hz") or 0.0)
    if mode == "outside_priors":
        lows = sensor_prior_lows(priors, fs_hz, natural_frequency_hz)
        if fr and fr * PRIOR_SLACK >= lows.get("resonance_hz", np.inf):
            fr = None  # inside: the model has read such resonances
        if fl and fl * PRIOR_SLACK >= lows.get("lowpass_hz", np.inf):
            fl = None
        if fh <= PRIOR_SLACK * sensor_prior_highpass_top(priors):
            fh = 0.0
    if mode == "resonance":
        fl, fh = None, 0.0
    contact = sensor.get("contact_hz")
    if fl and contact and fl < MIN_LOWPASS_RATIO * contact:
        fl = None  # it smooths the contact itself away: its inverse would invent the spike
    chain = SensorChain(
        resonance_hz=float(fr) if fr and zr else None,
        resonance_damping=float(zr) if fr and zr else None,
        lowpass_hz=float(fl) if fl and order else None,
        lowpass_order=int(order) if fl and order else None,
        highpass_hz=fh if np.isfinite(fh) and fh > 0 else 0.0,
        source=str(sensor.get("source") or "fitted"),
    )
    return chain if chain.has_dynamics or chain.highpass_hz > 0 else None


def trained_undo_chain(card: dict | None) -> str | None:
    """The undo mode a model's card asks for (its training config's ``undo_chain``), None
    where it names none.

    A model trained behind a campaign's own fitted chain (the loop's, its priors centred on
    that chain) has learned to read through it: the record with the chain divided out lies
    outside its world (the loop's GBM on a two-stage campaign behind a 240 Hz mount read
    β >= 60 35 % low with the chain undone, within 10 % as recorded; docs/measurement_loop.md).
    """
    mode = ((card or {}).get("config") or {}).get("undo_chain")
    return str(mode) if mode else None


def sensor_prior_highpass_top(priors: dict | None) -> float:
    """The highest high-pass corner (Hz) of the model's sensor prior (the card's
    ``data.priors``; infinity where the card gives none: every corner counts as inside)."""
    for effect in (priors or {}).get("effects") or []:
        if effect.get("name") == "sensor_dynamics":
            top = (effect.get("params") or {}).get("highpass_hz")
            if isinstance(top, list | tuple) and len(top) == 2:
                return float(top[1])
    return float("inf")


def undone_record(accel: np.ndarray, fs_hz: float, chain: SensorChain) -> np.ndarray:
    """`accel` divided by the chain's resonance and low-pass within the band it passes
    (:func:`~stiffnet.restoring_force.chain.deconvolve`) and by its high-pass
    (:func:`highpass_undone`), its ends reflected first."""
    a = np.asarray(accel, dtype=float)
    pad = min(a.size - 1, max(16, int(PAD_FRACTION * a.size)))
    padded = np.pad(a, pad, mode="reflect")
    flat = deconvolve(padded, fs_hz, chain, record_noise_sigma(a, fs_hz))
    return highpass_undone(flat[pad : pad + a.size], fs_hz, chain.highpass_hz)


def highpass_undone(y: np.ndarray, fs_hz: float, highpass_hz: float) -> np.ndarray:
    """`y` divided by a 1st-order high-pass at `highpass_hz` (the charge amplifier's,
    ``s / (s + w_h)``): ``y + w_h * integral of y``, the integral's constant and slope taken
    away (an acceleration's integral, the velocity, neither drifts nor has a known start).

    In time, not by FFT: the inverse is an integrator, and a periodic (reflected) record's
    ends would spread their error over every sample. `y` itself for no corner.
    """
    if not highpass_hz or highpass_hz <= 0:
        return y
    velocity = integrate.cumulative_trapezoid(y, dx=1.0 / fs_hz, initial=0.0)
    return y + 2.0 * np.pi * highpass_hz * signal.detrend(velocity)


def undone_windows(
    accel: np.ndarray, starts: np.ndarray, n_win: int, fs_hz: float, chain: SensorChain
) -> np.ndarray:
    """Windows ``accel[s : s + n_win]`` with the chain divided out, one by one.

    Each window is read with :func:`window_margin` samples of `accel` either side (reflected
    where `accel` ends) so that its ends do not leak into each other through the inverse,
    and with its own noise floor: a window's reading does not depend on how the record was
    cut into chunks, so a stream and the whole file give the same log.

    Returns
    -------
    numpy.ndarray
        ``(len(starts), n_win)``.
    """
    a = np.asarray(accel, dtype=float)
    m = window_margin(n_win)
    out = np.empty((len(starts), n_win))
    for k, s in enumerate(np.asarray(starts, dtype=int)):
        lo, hi = max(0, s - m), min(a.size, s + n_win + m)
        seg = np.pad(a[lo:hi], (m - (s - lo), m - (hi - s - n_win)), mode="reflect")
        flat = deconvolve(seg, fs_hz, chain, record_noise_sigma(seg, fs_hz))
        out[k] = highpass_undone(flat, fs_hz, chain.highpass_hz)[m : m + n_win]
    return out


def window_margin(n_win: int) -> int:
    """Samples of record read either side of a window whose chain is undone
    (:data:`PAD_FRACTION` of it, as a whole record's reflected ends)."""
    return max(16, int(PAD_FRACTION * n_win))


def model_record(
    accel: np.ndarray,
    fs_hz: float,
    natural_frequency_hz: float,
    restoring_force: dict[str, Any] | None,
    priors: dict | None,
    mode: str,
) -> tuple[np.ndarray, dict[str, Any] | None]:
    """The record the learned model reads, and what was undone (None: the record as is).

    Parameters
    ----------
    accel : numpy.ndarray
        The checked record.
    fs_hz, natural_frequency_hz : float
    restoring_force : dict or None
        The restoring-force cross-check of the same record (its ``sensor``).
    priors : dict or None
        The model card's ``data.priors``.
    mode : str
        One of :data:`UNDO_MODES`.

    Returns
    -------
    numpy.ndarray, dict or None
        The record, and the undone stages (``resonance_hz``, ``resonance_damping``,
        ``lowpass_hz``, ``lowpass_order``, ``highpass_hz``, ``source``) or None.
    """
    sensor = (restoring_force or {}).get("sensor")
    chain = chain_to_undo(sensor, priors, fs_hz, natural_frequency_hz, mode)
    if chain is None:
        return accel, None
    return undone_record(accel, fs_hz, chain), undone_stages(chain)


def undone_stages(chain: SensorChain) -> dict[str, Any]:
    """What dividing `chain` out undoes, as the results report it (``resonance_hz``,
    ``resonance_damping``, ``lowpass_hz``, ``lowpass_order``, ``highpass_hz``, ``source``)."""
    return {k: v for k, v in dataclasses.asdict(chain).items()
            if k in ("resonance_hz", "resonance_damping", "lowpass_hz", "lowpass_order",
                     "highpass_hz", "source")}  # fmt: skip


def chain_as_read(sensor: dict | None, undone: dict[str, Any] | None) -> dict | None:
    """The identified chain as the model read it: the stages :func:`model_record` divided out
    taken away (what the alarm's sensor check judges against the model's priors). `sensor`
    itself where nothing was undone."""
    if not sensor or not undone:
        return sensor
    left = dict(sensor)
    if undone.get("resonance_hz"):
        left.update(resonance_hz=None, resonance_damping=None)
    if undone.get("lowpass_hz"):
        left.update(lowpass_hz=None, lowpass_order=None)
    if undone.get("highpass_hz"):
        left.update(highpass_hz=0.0)
    return left
