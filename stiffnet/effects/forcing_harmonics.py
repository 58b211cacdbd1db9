"""Shaker distortion: 2nd and 3rd harmonics in the base excitation."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from stiffnet.effects.base import (
    DynamicsEffect,
    EffectParams,
    ParamArrays,
    ParamValue,
    Sinusoids,
    param,
)
from stiffnet.effects.fit_space import FitParam, FitSpace, Polar


class ForcingHarmonics(DynamicsEffect):
    r"""Harmonic distortion of the electro-dynamic shaker.

    The base acceleration is no longer a pure sine; the forcing of eq. (12) becomes

    .. math:: F(t) = a\omega^2\bigl[\sin\omega t + h_2 \sin(2\omega t + \varphi_2)
              + h_3 \sin(3\omega t + \varphi_3)\bigr]

    with :math:`h_2, h_3` the harmonic amplitudes relative to the fundamental
    (a few percent on real shakers, more near their own resonances or at large
    stroke). The model stays piecewise linear, so it is solved in closed form.

    Signature on the acceleration: lines at :math:`2\omega` and :math:`3\omega` in
    the spectrum of the free flight; with the table's motion, the absolute
    acceleration of a non-impacting mass is no longer a pure sine.
    """

    name = "forcing_harmonics"
    neutral = {"second": 0.0, "third": 0.0}
    #: Training-world prior (docs/priors.md): shaker distortion with any phase.
    prior: ClassVar[dict | None] = {
        "probability": 0.5,
        "params": {
            "second": [0.0, 0.3],
            "third": [0.0, 0.15],
            "phase_second": [-3.14159, 3.14159],
            "phase_third": [-3.14159, 3.14159],
        },
    }

    class Params(EffectParams):
        second: ParamValue = param(0.05, 0.0, 0.5, "2nd-harmonic amplitude / fundamental")
        third: ParamValue = param(0.02, 0.0, 0.5, "3rd-harmonic amplitude / fundamental")
        phase_second: ParamValue = param(0.0, -np.pi, np.pi, "phase of the 2nd harmonic", "rad")
        phase_third: ParamValue = param(0.0, -np.pi, np.pi, "phase of the 3rd harmonic", "rad")

    #: Both harmonics with their phases, each pair fitted as (h cos phi, h sin phi).
    fit_space = FitSpace(
        (
            FitParam("second_cos", -0.5, 0.5),
            FitParam("second_sin", -0.5, 0.5),
            FitParam("third_cos", -0.5, 0.5),
            FitParam("third_sin", -0.5, 0.5),
        ),
        polar=(Polar("second", "phase_second", 0.5), Polar("third", "phase_third", 0.5)),
        # the phases are multimodal, but not declared so: with the initial states held
        # while a fit moves them, a recording jumps orbit and the sweep finds lower-scoring
        # points away from the truth (8 recordings, 0.25/1.1 and 0.12/-2.0: with the sweep
        # 0.225/1.65 and 0.076/2.87, without 0.253/1.08 and 0.104/-2.07); the Cartesian
        # pair keeps the phase smooth for the local search
    )

    def forcing_terms(self, p: ParamArrays, batch: Any) -> Sinusoids:
        scale = batch.amplitude * batch.omega**2
        amp = np.stack([p["second"] * scale, p["third"] * scale], axis=1)
        freq = np.stack([2 * batch.omega, 3 * batch.omega], axis=1)
        phase = np.stack([p["phase_second"], p["phase_third"]], axis=1)
        return Sinusoids(amp, freq, phase)
