"""Analog-to-digital conversion: finite resolution and a finite input range (clipping)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

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


def lsb(full_scale: np.ndarray, bits: np.ndarray) -> np.ndarray:
    """Quantisation step of the symmetric mid-tread quantiser used by :class:`ADC`.

    Parameters
    ----------
    full_scale : numpy.ndarray
        Full-scale amplitude (same units as the signal).
    bits : numpy.ndarray
        Resolution in bits (integers).

    Returns
    -------
    numpy.ndarray
        ``full_scale / (2**(bits - 1) - 1)``.
    """
    return full_scale / (2.0 ** (np.asarray(bits, dtype=np.float64) - 1.0) - 1.0)


class ADC(MeasurementEffect):
    r"""Quantisation and clipping of the acquisition card.

    Each row is converted with a full-scale range ``[-FS, +FS]``,
    ``FS = full_scale * a w^2`` (the input range of the card / amplifier gain
    setting, expressed as a multiple of the row's forcing scale):

    * values beyond ``+/- FS`` are **clipped**: the impact spikes of a
      badly ranged channel come out as flat tops at exactly ``+/- FS``;
    * the rest are **rounded** to the nearest level of a mid-tread quantiser
      (zero is a level, so a quiet signal reads exactly 0)::

          q = FS / (2**(bits - 1) - 1),   y = q * round(clip(x, -FS, FS) / q)

      The levels ``k q``, ``|k| <= 2**(bits - 1) - 1``, are symmetric and
      include ``+/- FS``: ``2**bits - 1`` distinct values, the usual symmetric
      use of a ``bits``-bit two's-complement code (the most negative code is
      left unused). Inside the range the error is at most ``q / 2``.

    Laboratory cards (e.g. the NI boards read through LabVIEW in the paper's
    rig) have 12-24 bits over ranges of +/-0.1 to +/-10 V; the error that
    matters is the ratio of the spike height to the range chosen by the
    experimenter, hence the default range of 200 a w^2 (generous, no clipping)
    with 16 bits. ``bits`` drawn from a range is rounded to an integer.
    """

    name = "adc"
    #: Training-world prior (docs/priors.md): converter resolution and input range.
    prior: ClassVar[dict | None] = {
        "probability": 0.4,
        "params": {"bits": [10.0, 16.0], "full_scale": [30.0, 300.0]},
    }
    order = 90

    class Params(EffectParams):
        bits: ParamValue = param(
            16.0,
            4,
            24,
            "resolution of the converter (rounded to an integer)",
            "bit",
            integer=True,
        )
        full_scale: ParamValue = param(
            200.0, 0.5, 10000.0, "full-scale amplitude +/-FS as a multiple of a w^2", ""
        )

    #: Resolution and full scale (clipping and quantisation).
    fit_space = FitSpace(
        (FitParam("bits", 4.0, 16.0), FitParam("full_scale", 1.0, 1000.0, log=True))
    )

    def apply(
        self, signal: np.ndarray, fs_hz: np.ndarray, p: ParamArrays, rng: np.random.Generator
    ) -> np.ndarray:
        """Clip each row to ``+/- full_scale * a w^2`` and quantise it to ``bits`` bits.

        Parameters
        ----------
        signal : numpy.ndarray
            Accelerations, shape ``(B, N)``, model units.
        fs_hz : numpy.ndarray
            Sampling rate of each row in Hz (unused).
        p : dict of numpy.ndarray
            Per-row ``bits`` and ``full_scale`` and the context ``"_forcing_scale"``,
            each ``(B,)``.
        rng : numpy.random.Generator
            Unused (the conversion is deterministic).

        Returns
        -------
        numpy.ndarray
            Quantised signal, a new ``(B, N)`` float64 array.
        """
        x = batch_signal(signal)
        b = x.shape[0]

        def row(key: str) -> np.ndarray:
            return per_row(p, key, b)

        bits = np.rint(row("bits"))
        top = (2.0 ** (bits - 1.0) - 1.0)[:, None]  # largest code, as a float
        q = lsb(row("full_scale") * np.abs(row("_forcing_scale")), bits)[:, None]
        # clip in code units so clipped samples land exactly on the +/-top code; a zero
        # range (no forcing) reads 0 everywhere
        with np.errstate(divide="ignore", invalid="ignore"):
            codes = np.clip(np.rint(x / q), -top, top)
        return np.where(q > 0, codes * q, 0.0)
