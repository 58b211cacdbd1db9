"""User-written effects, loaded by ``"user_effects:ClassName"`` in the effect tests.

They show the two kinds of user extension: a dynamics effect through a
closed-form hook (the model stays piecewise linear, so the exact engine runs)
and a measurement effect.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from stiffnet.effects.base import (
    DynamicsEffect,
    EffectParams,
    MeasurementEffect,
    ParamArrays,
    ParamValue,
    Sinusoids,
    param,
)
from stiffnet.effects.forcing_harmonics import ForcingHarmonics
from stiffnet.effects.learned_contact import elastic_shape


class ConstantPreload(DynamicsEffect):
    """A constant force on the mass towards the restraint (e.g. its weight on a vertical rig).

    It enters the forcing as a sinusoid of zero frequency and phase pi/2. The
    free mass sags by ``force`` (unit primary stiffness) and the accelerometer,
    which reads specific force, shows the offset ``-force``.
    """

    name = "constant_preload"

    class Params(EffectParams):
        force: ParamValue = param(0.2, -5.0, 5.0, "constant force / primary stiffness", "model")

    def forcing_terms(self, p: ParamArrays, batch: Any) -> Sinusoids:
        n = len(batch)
        return Sinusoids(p["force"][:, None], np.zeros((n, 1)), np.full((n, 1), np.pi / 2))


class Gain(MeasurementEffect):
    """A miscalibrated sensitivity: the recorded signal times ``gain``."""

    name = "gain"
    order = 15  # after the sensor, before the baseline noise

    class Params(EffectParams):
        gain: ParamValue = param(1.0, 0.1, 10.0, "sensitivity error factor")

    def apply(
        self, signal: np.ndarray, fs_hz: np.ndarray, p: ParamArrays, rng: np.random.Generator
    ) -> np.ndarray:
        return signal * p["gain"][:, None]


class StiffeningContact(DynamicsEffect):
    """A two-stage restraint (a contact law the diagnosed library lacks): the spring ``beta``
    until the penetration reaches ``knee``, then ``ratio`` times stiffer (a beam that bottoms
    out on a stop). Elastic, so it needs the numerical engine.

    The law is the library's one two-stage shape
    (:func:`stiffnet.effects.learned_contact.elastic_shape` with a linear first stage), as a
    user effect of two parameters: the diagnosis does not search ``learned_contact``."""

    name = "stiffening_contact"

    class Params(EffectParams):
        knee: ParamValue = param(0.05, 1e-3, 1.0, "penetration of the second stage", "model length")
        ratio: ParamValue = param(4.0, 1.0, 20.0, "stiffness of the second stage over beta")

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        law = {"exponent": 1.0, "reference_penetration": 1.0, "preload": 0.0,
               "knee": p["knee"], "knee_ratio": p["ratio"]}  # fmt: skip
        return np.asarray(batch.beta, float) * elastic_shape(delta, law)


class PhasedHarmonics(ForcingHarmonics):
    """The shaker's harmonics with their phases declared multimodal (the global fit stage's
    tests: a user effect that widens a library effect's fit space)."""

    name = "phased_harmonics"
    fit_space = replace(
        ForcingHarmonics.fit_space, multimodal=("phase_second", "phase_third"), global_seeds=False
    )
