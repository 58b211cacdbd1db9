"""Contact laws the effect library lacks, written as user effects (``module:Class``).

Their one home: the contact-law discovery (:mod:`stiffnet.discovery`), the
unseen-law alarm and the learned law are tested on them, and the robustness
benchmark (``benchmarks/bench_robustness.py``) hides them in test rigs to see what
the models and the alarm do on physics they were never trained on (loaded there as
the plugin file ``unknown_contact_laws``). Nothing here is library code, and their
parametrisations are their own (a Hunt-Crossley law written with its
restitution-like coefficient, a two-stage restraint with its own knee and ratio),
so the discovery must find the terms and convert the coefficients, not read them
back. They are also the worked example of a user effect: a ``DynamicsEffect``
subclass that overrides ``elastic_contact`` (the simulator then integrates
numerically with event location).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stiffnet.effects.base import DynamicsEffect, EffectParams, ParamArrays, ParamValue, param


class PowerLawContact(DynamicsEffect):
    """``F = k_p delta**n`` with ``k_p = beta / d0**(n - 1)`` (secant ``beta`` at ``d0``).

    ``n = 1`` is the paper's linear restraint, ``n = 1.5`` Hertz's sphere on a flat (the
    library's ``hertz_contact``); rough or conforming contacts and layered rock show
    other exponents.
    """

    name = "unknown_power_law"

    class Params(EffectParams):
        exponent: ParamValue = param(2.0, 1.0, 3.0, "exponent n")
        d0: ParamValue = param(0.5, 1e-3, 10.0, "penetration of secant stiffness beta", "model")

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        return batch.beta * p["d0"] ** (1.0 - p["exponent"]) * delta ** p["exponent"]


class TwoStageContact(DynamicsEffect):
    """A soft first stage of stiffness ``beta`` up to ``knee``, then ``beta + k2`` beyond,
    with ``k2 = (ratio - 1) beta`` (a layer over a stiffer body)."""

    name = "unknown_two_stage"

    class Params(EffectParams):
        knee: ParamValue = param(0.1, 1e-3, 1.0, "penetration of the second stage", "model")
        ratio: ParamValue = param(4.0, 1.0, 20.0, "second-stage stiffness over beta")

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        beta = np.asarray(batch.beta, float)
        return np.where(
            delta <= p["knee"],
            beta * delta,
            beta * p["knee"] + p["ratio"] * beta * (delta - p["knee"]),
        )


class HuntCrossleyContact(DynamicsEffect):
    """Hunt & Crossley (1975): ``F = beta delta (1 + 1.5 c v)``, ``c`` the law's own
    coefficient (restitution ``e ~ 1 - c v_in`` at low impact speed).

    The damping force grows with the penetration (zero at first touch, so no force jump
    at onset), unlike the library's Kelvin-Voigt ``contact_damping`` (``c v``); wet or
    crushing rock, rubber pads.
    """

    name = "unknown_hunt_crossley"

    class Params(EffectParams):
        c: ParamValue = param(0.3, 0.0, 5.0, "Hunt-Crossley coefficient", "model time/length")

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        return np.asarray(batch.beta, float) * delta

    def contact_dissipation(
        self, delta: np.ndarray, rate: np.ndarray, p: ParamArrays, batch: Any
    ) -> np.ndarray:
        return 1.5 * p["c"] * np.asarray(batch.beta, float) * delta * rate


class SprungFaceContact(DynamicsEffect):
    """A linear contact (stiffness ``beta``) against a face that has its own mass and rings:
    the face (mass ``m_f`` over the mass m) sits on a support that makes it ring at
    ``f_face`` times the mass's natural frequency, with a loss factor ``eta`` (twice its
    damping ratio); ``y`` is the face's recoil, pushed by the contact force::

        m_f y'' + eta f_face m_f y' + m_f f_face**2 y = F_c,   F_c = beta (x - e - y)_+
    """

    name = "test_sprung_face"
    n_states = 2

    class Params(EffectParams):
        m_f: ParamValue = param(0.5, 1e-3, 10.0, "face mass over the mass m")
        f_face: ParamValue = param(8.0, 0.5, 100.0, "face frequency over the natural frequency")
        eta: ParamValue = param(0.2, 0.0, 2.0, "loss factor of the face's support")

    def fastest_rate(self, p: ParamArrays, batch: Any) -> np.ndarray:
        k = 1.0 + batch.beta + (p["m_f"] * p["f_face"] ** 2 + batch.beta) / p["m_f"]
        c = p["eta"] * p["f_face"]
        return 0.5 * c + np.sqrt(0.25 * c * c + k)

    def restraint_position(self, s: np.ndarray, p: ParamArrays) -> np.ndarray:
        return s[:, 0]

    def state_derivative(
        self, t: np.ndarray, s: np.ndarray, contact_force: np.ndarray, p: ParamArrays
    ) -> np.ndarray:
        m, w, eta = p["m_f"], p["f_face"], p["eta"]
        return np.stack([s[:, 1], contact_force / m - eta * w * s[:, 1] - w * w * s[:, 0]], 1)


class BeamTipContact(DynamicsEffect):
    """A linear contact (stiffness ``beta``) on the tip of a cantilever, its first two bending
    modes: the beam (mass ``m_b`` over the mass m) has each mode's tip mass a quarter of its
    own (Euler-Bernoulli, tip-normalised shapes), the first ringing at ``f_1`` natural
    frequencies and the second at ``(4.6941 / 1.8751)**2 f_1``, both with damping ratio
    ``zeta``; the tip's recoil is the sum of the modes', each pushed by the contact force::

        (m_b / 4) (y_i'' + 2 zeta w_i y_i' + w_i**2 y_i) = F_c,   F_c = beta (x - e - y_1 - y_2)_+
    """

    name = "test_beam_tip"
    n_states = 4

    class Params(EffectParams):
        m_b: ParamValue = param(0.4, 1e-3, 10.0, "beam mass over the mass m")
        f_1: ParamValue = param(10.0, 0.5, 100.0, "first mode over the natural frequency")
        zeta: ParamValue = param(0.05, 0.0, 1.0, "damping ratio of each mode")

    @staticmethod
    def frequencies(p: ParamArrays) -> tuple[Any, Any]:
        return p["f_1"], p["f_1"] * (4.6940911 / 1.8751041) ** 2

    def fastest_rate(self, p: ParamArrays, batch: Any) -> np.ndarray:
        w2 = self.frequencies(p)[1]
        k = 1.0 + batch.beta + w2 * w2 + 8.0 * batch.beta / p["m_b"]
        c = 2.0 * p["zeta"] * w2
        return 0.5 * c + np.sqrt(0.25 * c * c + k)

    def restraint_position(self, s: np.ndarray, p: ParamArrays) -> np.ndarray:
        return s[:, 0] + s[:, 2]

    def state_derivative(
        self, t: np.ndarray, s: np.ndarray, contact_force: np.ndarray, p: ParamArrays
    ) -> np.ndarray:
        m = 0.25 * p["m_b"]
        out = []
        for i, w in enumerate(self.frequencies(p)):
            y, v = s[:, 2 * i], s[:, 2 * i + 1]
            out += [v, contact_force / m - 2.0 * p["zeta"] * w * v - w * w * y]
        return np.stack(out, 1)


class PreloadedPowerLawContact(DynamicsEffect):
    """A power-law restraint already compressed by ``pre`` before the mass arrives:
    ``F = k_p (delta + pre)**n`` with ``k_p = beta / d0**(n - 1)``, so the force jumps to
    ``k_p pre**n`` at first touch (a bolted pad, a spring set against its stop).

    ``n = 1`` is a linear spring with a force step ``beta pre`` at touch.
    """

    name = "unknown_preloaded_power_law"

    class Params(EffectParams):
        exponent: ParamValue = param(1.5, 1.0, 3.0, "exponent n")
        d0: ParamValue = param(0.5, 1e-3, 10.0, "penetration of secant stiffness beta", "model")
        pre: ParamValue = param(0.1, 0.0, 1.0, "compression before first touch", "model")

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        k = np.asarray(batch.beta, float) * p["d0"] ** (1.0 - p["exponent"])
        return k * (np.maximum(delta, 0.0) + p["pre"]) ** p["exponent"]
