"""Slow variation of the gap during a recording."""

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
from stiffnet.effects.fit_space import FitParam, FitSpace


class GapDrift(DynamicsEffect):
    r"""The gap wanders slowly: thermal growth, a loosening bolt, bit wear, feed.

    .. math:: e(t) = e + \Delta e\,\sin\!\left(\frac{2\pi t}{T_d} + \varphi\right)

    with :math:`T_d` the drift period in natural periods (:math:`2\pi` model
    time units each), much longer than a forcing period. The restraint moves, so
    in contact its spring (and damper) act on :math:`x - e(t)`; the model stays
    piecewise linear and is solved in closed form.

    Signature on the acceleration: the impact spikes' height and the impact rate
    change slowly over the recording (and impacts may come and go).
    """

    name = "gap_drift"
    neutral = {"amplitude": 0.0}
    #: Training-world prior (docs/priors.md): slow drift of the gap.
    prior: ClassVar[dict | None] = {
        "probability": 0.3,
        "params": {"amplitude": [0.0, 0.3], "period": [50.0, 1000.0], "phase": [-3.14159, 3.14159]},
    }

    class Params(EffectParams):
        amplitude: ParamValue = param(
            0.2, 0.0, 2.0, "amplitude of the gap variation", "model length"
        )
        period: ParamValue = param(
            200.0,
            10.0,
            1e5,
            "drift period in natural periods (2 pi model time)",
            "natural periods",
        )
        phase: ParamValue = param(0.0, -np.pi, np.pi, "phase of the drift at t = 0", "rad")

    #: Amplitude, period and phase of the drift (a slow drift's phase sets which part of
    #: its cycle a short record sees).
    fit_space = FitSpace(
        (
            FitParam("amplitude", 0.0, 1.0),
            FitParam("period", 10.0, 1000.0, log=True),
            FitParam("phase", -np.pi, np.pi),
        ),
        multimodal=("period", "phase"),
    )

    def gap_terms(self, p: ParamArrays, batch: Any) -> Sinusoids:
        freq = 1.0 / p["period"]  # 2 pi / (2 pi * period)
        return Sinusoids(p["amplitude"][:, None], freq[:, None], p["phase"][:, None])
