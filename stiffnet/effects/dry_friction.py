"""Coulomb (dry) friction of the mass in its guides, with stick-slip."""

from __future__ import annotations

import numpy as np

from stiffnet.effects.base import DynamicsEffect, EffectParams, ParamArrays, ParamValue, param
from stiffnet.effects.fit_space import FitParam, FitSpace

#: Discrete modes of :class:`DryFriction`.
SLIP_FORWARD = 0.0
STUCK = 1.0
SLIP_BACKWARD = -1.0

#: ``copysign(1, mode - _SLIP_SIGN)``: +1 for ``SLIP_FORWARD``, -1 for ``SLIP_BACKWARD``.
_SLIP_SIGN = -0.5

_V_TOL = 1e-9
"""|v| below this at an event counts as a velocity reversal (a located event has |v| ~ 1e-15)."""


class DryFriction(DynamicsEffect):
    r"""Coulomb friction in the guides of the mass, with sticking.

    A force of constant magnitude ``mu_k = coefficient`` opposes the relative
    velocity of the mass and its guides (they move with the table, so the
    relative velocity is ``v``); while the mass is stuck the friction balances
    all other forces, up to the static level ``mu_s = static_ratio * mu_k``::

        slipping:  f = -mu_k sign(v)
        stuck:     f = -other,   v = 0,   held while |other| <= mu_s

    ``other`` is the sum of all other forces on the mass in the relative frame
    (base forcing, spring, damper, contact). Forces are in the model's units
    (primary-spring force per model length), so ``coefficient`` compares
    directly with the forcing amplitude ``a w^2`` (about 2.1 in the paper).

    Modes (``mode`` array): ``SLIP_FORWARD`` (0, ``v > 0``, ``f = -mu_k``),
    ``SLIP_BACKWARD`` (-1, ``v < 0``, ``f = +mu_k``) and ``STUCK`` (1). The
    slip direction is part of the mode, not read from ``sign(v)``, so the force
    is frozen (smooth) between events and the RK4 substeps stay fourth order.
    Event functions (positive while the mode holds): ``v`` resp. ``-v`` while
    slipping, ``mu_s - |other|`` while stuck. At a velocity reversal the mass
    sticks if ``|other| <= mu_s``, otherwise it slips on in the direction of
    ``other``; a stuck mass breaks loose in the direction of ``other``.

    Signature on the acceleration: at every velocity reversal the friction
    force flips, a step of ``2 mu_k`` in the (absolute) acceleration; while
    stuck the mass moves with the table, its acceleration is the table's
    (``-a w^2 sin(w t)``) and its relative displacement is flat. The response
    amplitude drops (friction dissipates ``4 mu_k X`` per cycle).
    """

    name = "dry_friction"

    class Params(EffectParams):
        coefficient: ParamValue = param(
            0.05,
            0.0,
            10.0,
            "kinetic friction force (model force units, cf. a w^2)",
            "model acceleration",
        )
        static_ratio: ParamValue = param(
            1.2, 1.0, 5.0, "static over kinetic friction force (breakaway level)", ""
        )

    #: The kinetic friction force; the breakaway ratio held at the default.
    fit_space = FitSpace(
        (FitParam("coefficient", 0.001, 1.0, log=True),), fixed={"static_ratio": 1.2}
    )

    def extra_force(
        self,
        t: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        other: np.ndarray,
        mode: np.ndarray,
        p: ParamArrays,
    ) -> np.ndarray:
        """Friction force on the mass, (B,): ``-other`` when stuck, ``-/+ mu_k`` slipping."""
        # the slip's sign from the mode (+ backward, - forward) by one copysign: the engine
        # calls this at every right-hand side, where each numpy call's cost is the cost
        return np.where(mode == STUCK, -other, np.copysign(p["coefficient"], _SLIP_SIGN - mode))

    def event_function(
        self,
        t: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        other: np.ndarray,
        mode: np.ndarray,
        p: ParamArrays,
    ) -> np.ndarray:
        """Positive while the mode holds: ``+/-v`` slipping, ``mu_s - |other|`` stuck."""
        mu_s = p["static_ratio"] * p["coefficient"]
        return np.where(
            mode == STUCK, mu_s - np.abs(other), np.copysign(1.0, mode - _SLIP_SIGN) * v
        )

    def event_rate(
        self,
        t: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        accel: np.ndarray,
        other: np.ndarray,
        mode: np.ndarray,
        p: ParamArrays,
    ) -> np.ndarray:
        """Rate of :meth:`event_function`: ``+/-accel`` slipping (the function is ``+/-v``);
        NaN stuck (``|other|``'s rate is not in the state), where the secant locates it."""
        return np.where(mode == STUCK, np.nan, np.where(mode == SLIP_BACKWARD, -accel, accel))

    def next_mode(
        self, x: np.ndarray, v: np.ndarray, other: np.ndarray, mode: np.ndarray, p: ParamArrays
    ) -> np.ndarray:
        """Mode after an event: stick at a reversal if ``|other| <= mu_s``, else slip.

        Also gives the initial mode (called from ``SLIP_FORWARD`` when ``v0 <= 0``):
        a clearly nonzero velocity sets the slip direction.
        """
        mu_s = p["static_ratio"] * p["coefficient"]
        toward = np.where(other < 0, SLIP_BACKWARD, SLIP_FORWARD)
        moving = np.abs(v) > _V_TOL
        slip = np.where(moving, np.where(v < 0, SLIP_BACKWARD, SLIP_FORWARD), toward)
        sticks = ~moving & (np.abs(other) <= mu_s)
        return np.where(mode == STUCK, toward, np.where(sticks, STUCK, slip))
