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

An effect also declares which of its parameters make the objective
*multimodal* (``multimodal``: phases, resonance or drift frequencies, knots):
a local search started in the wrong basin of one of them stops short of the
truth, so the fit sweeps a grid over each of them (:func:`global_blocks`)
before its local search. An effect whose multimodal parameters can be read off the
measurement in closed form (a harmonic's phase: :mod:`stiffnet.measurement.forcing_lines`)
declares ``global_seeds``: its data-driven seeds are the global stage, and the
local search starts from the best of them, with a small first step.
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
    multimodal : tuple of str
        Parameters swept on a grid before the local search (see the module notes).
    global_seeds : bool
        The effect's data-driven seeds replace the grid over the multimodal parameters
        (see the module notes).
    """

    free: tuple[FitParam, ...]
    fixed: Mapping[str, float] = field(default_factory=dict)
    polar: tuple[Polar, ...] = ()
    #: Parameters whose objective has several basins (a free parameter, or the phase of a
    #: :class:`Polar` pair): each is swept on a grid before the local search.
    multimodal: tuple[str, ...] = ()
    #: The multimodal parameters are read off the measurement (the effect's ``fit_seeds``):
    #: the seeds are the global stage, no grid is swept.
    global_seeds: bool = False

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


#: Grid of a multimodal free coordinate (points across its unit interval).
AXIS_GRID = 9
#: Grid of a multimodal phase: angles, and amplitudes as fractions of the pair's maximum.
PHASE_GRID = 8
AMPLITUDE_LEVELS = (0.1, 0.3, 0.6)


def global_blocks(space: FitSpace) -> list[tuple[list[int], np.ndarray]]:
    """The global stage's sweeps: for each multimodal parameter, the free coordinates it
    moves (their indices) and the grid of their unit-cube values (one row per point).

    A free coordinate gets :data:`AXIS_GRID` points across its interval; the phase of a
    polar pair gets :data:`PHASE_GRID` angles at each of :data:`AMPLITUDE_LEVELS`
    (the pair's two Cartesian coordinates move together). None for a space whose
    ``global_seeds`` stand for the grid."""
    names = space.names
    out = []
    if space.global_seeds:  # the effect's seeds stand for the grid
        return out
    for m in space.multimodal:
        pair = next((p for p in space.polar if m in (p.phase, p.amplitude)), None)
        if pair is not None:
            idx = [names.index(n) for n in pair.names]
            fps = [space.free[i] for i in idx]
            pts = [
                [fps[0].unit(r * pair.max_amplitude * math.cos(a)),
                 fps[1].unit(r * pair.max_amplitude * math.sin(a))]
                for r in AMPLITUDE_LEVELS
                for a in np.linspace(-math.pi, math.pi, PHASE_GRID, endpoint=False)
            ]  # fmt: skip
            out.append((idx, np.array(pts)))
        elif m in names:
            out.append(([names.index(m)], np.linspace(0.0, 1.0, AXIS_GRID)[:, None]))
        else:
            raise ValueError(f"multimodal {m!r} is not a free parameter nor a polar phase")
    return out


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
