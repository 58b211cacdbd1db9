"""Fit spaces: which parameters of an effect are fitted to a measurement, and where.

Every effect declares, next to its parameters, the space in which the
measurement loop (:mod:`stiffnet.measurement.fitting`) fits it to a campaign:
the *free* parameters with their search interval and scale and the *fixed* ones
(held where they leave the effect's core alone). "Effect off" is the effect's
``neutral`` parameters (:class:`stiffnet.effects.base.Effect`). A pair of
parameters that is an amplitude and a phase (a harmonic) is fitted in Cartesian
coordinates ``(A cos phi, A sin phi)``: the objective is smooth there, with no
wrap-around at +-pi and no degenerate phase at zero amplitude.

The search works in the unit cube: :meth:`FitSpace.params` maps a point of it
to the effect's parameters, :meth:`FitSpace.unit` back.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class FitParam:
    """One fitted coordinate: its search interval and scale (log when ``log``)."""

    name: str
    low: float
    high: float
    log: bool = False

    def unit(self, v: float) -> float:
        """The unit-interval coordinate of a value (inverse of :meth:`value`), clipped."""
        if self.log:
            u = (math.log(max(v, self.low)) - math.log(self.low)) / (
                math.log(self.high) - math.log(self.low)
            )
        else:
            u = (v - self.low) / (self.high - self.low) if self.high > self.low else 0.0
        return float(np.clip(u, 0.0, 1.0))

    def value(self, u: float) -> float:
        """The value at unit-interval coordinate ``u`` (clipped to ``[0, 1]``)."""
        u = float(np.clip(u, 0.0, 1.0))
        if self.log:
            v = math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low)))
        else:
            v = self.low + u * (self.high - self.low)
        return float(min(max(v, self.low), self.high))  # rounding must not leave the range


@dataclass(frozen=True)
class Polar:
    """An amplitude/phase pair fitted as ``amplitude * (cos phase, sin phase)``.

    The free coordinates are ``<amplitude>_cos`` and ``<amplitude>_sin``; the
    amplitude is clipped to ``max_amplitude`` (its declared range).
    """

    amplitude: str
    phase: str
    max_amplitude: float

    @property
    def names(self) -> tuple[str, str]:
        return f"{self.amplitude}_cos", f"{self.amplitude}_sin"


@dataclass(frozen=True)
class FitSpace:
    """Free and fixed parameters of an effect (see the module notes).

    Attributes
    ----------
    free : tuple of FitParam
        Fitted coordinates (effect parameters, or the Cartesian pair of a :class:`Polar`).
    fixed : mapping
        Parameters held at these values while fitting.
    polar : tuple of Polar
        Amplitude/phase pairs fitted in Cartesian coordinates.
    """

    free: tuple[FitParam, ...]
    fixed: Mapping[str, float] = field(default_factory=dict)
    polar: tuple[Polar, ...] = ()

    @property
    def names(self) -> list[str]:
        """The free coordinates' names."""
        return [fp.name for fp in self.free]

    @property
    def fitted(self) -> list[str]:
        """The effect parameters the fit sets (amplitudes and phases for a polar pair)."""
        cart = {n for p in self.polar for n in p.names}
        out = [n for n in self.names if n not in cart]
        for p in self.polar:
            out += [p.amplitude, p.phase]
        return out

    def params(self, u: np.ndarray) -> dict[str, float]:
        """Effect parameters at the unit-cube point ``u`` (fixed ones included)."""
        out = dict(self.fixed)
        out.update({fp.name: fp.value(x) for fp, x in zip(self.free, u, strict=True)})
        for p in self.polar:
            c, s = (out.pop(n) for n in p.names)
            out[p.amplitude] = float(min(math.hypot(c, s), p.max_amplitude))
            out[p.phase] = float(math.atan2(s, c)) if (c or s) else 0.0
        return out

    def unit(self, params: Mapping[str, float]) -> np.ndarray:
        """The unit-cube point of effect parameters (inverse of :meth:`params`)."""
        coords = dict(params)
        for p in self.polar:
            a, ph = float(params.get(p.amplitude, 0.0)), float(params.get(p.phase, 0.0))
            coords[p.names[0]], coords[p.names[1]] = a * math.cos(ph), a * math.sin(ph)
        return np.array([fp.unit(float(coords[fp.name])) for fp in self.free])


def default_fit_space(table: list[dict]) -> FitSpace:
    """Every parameter with a finite declared range, log scale when the range is positive and
    spans more than two decades (the fit space of an effect that declares none)."""
    free = []
    for row in table:
        lo, hi = row["range"]
        if lo is None or hi is None or not hi > lo:
            continue
        free.append(FitParam(row["name"], float(lo), float(hi), log=lo > 0 and hi / lo > 100))
    return FitSpace(tuple(free))
