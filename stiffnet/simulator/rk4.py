"""Classical RK4 steps of the numerical engine's batch (:mod:`.numerical`): a step, a step
with its stages, and the continuous extension between its ends (dense output)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from stiffnet.simulator.numerical import _Model


def _rk4(
    model: _Model,
    t: np.ndarray,
    y: np.ndarray,
    k1: np.ndarray,
    s: np.ndarray,
    contact: np.ndarray,
    modes: np.ndarray,
) -> np.ndarray:
    """One classical RK4 step of length ``s`` (per row) from ``(t, y)``; ``k1 = f(t, y)``.

    By the compiled kernel where the model has one (``model.kernel``, the library's own
    effects: :mod:`.rk4_kernel`), bitwise the same states."""
    if model.kernel is not None:
        return model.rk4_stages(t, y, k1, s, contact, modes)[0]
    half = 0.5 * s
    tm = t + half
    fm = model.forcing_at(tm)  # k2 and k3 share the midpoint time
    k2, _ = model.rhs(tm, y + half[:, None] * k1, contact, modes, forcing=fm)
    k3, _ = model.rhs(tm, y + half[:, None] * k2, contact, modes, forcing=fm)
    k4, _ = model.rhs(t + s, y + s[:, None] * k3, contact, modes)
    return y + (s / 6.0)[:, None] * (k1 + 2.0 * (k2 + k3) + k4)


def _rk4_dense(
    model: _Model,
    t: np.ndarray,
    y: np.ndarray,
    k1: np.ndarray,
    s: np.ndarray,
    contact: np.ndarray,
    modes: np.ndarray,
) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """:func:`_rk4` (the same arithmetic) and its stages ``(k1, k2, k3, k4)``, for
    :func:`_dense_states`."""
    if model.kernel is not None:
        return model.rk4_stages(t, y, k1, s, contact, modes)
    half = 0.5 * s
    tm = t + half
    fm = model.forcing_at(tm)
    k2, _ = model.rhs(tm, y + half[:, None] * k1, contact, modes, forcing=fm)
    k3, _ = model.rhs(tm, y + half[:, None] * k2, contact, modes, forcing=fm)
    k4, _ = model.rhs(t + s, y + s[:, None] * k3, contact, modes)
    return y + (s / 6.0)[:, None] * (k1 + 2.0 * (k2 + k3) + k4), (k1, k2, k3, k4)


def _dense_states(
    y: np.ndarray,
    s: np.ndarray,
    stages: tuple[np.ndarray, ...],
    rows: np.ndarray,
    theta: np.ndarray,
) -> np.ndarray:
    """States at fractions ``theta`` of an RK4 step of length ``s`` from ``y``, for rows
    ``rows`` (one entry per point): the classical RK4 continuous extension (third order,
    Hairer, Norsett & Wanner, *Solving ODEs I*, II.6), whose weights reach RK4's at
    ``theta = 1``; it needs no further evaluation of the right-hand side."""
    th2, th3 = theta * theta, theta * theta * theta
    b1 = theta - 1.5 * th2 + (2.0 / 3.0) * th3
    b23 = th2 - (2.0 / 3.0) * th3
    b4 = -0.5 * th2 + (2.0 / 3.0) * th3
    k1, k2, k3, k4 = (k[rows] for k in stages)
    inc = b1[:, None] * k1 + b23[:, None] * (k2 + k3) + b4[:, None] * k4
    return y[rows] + s[rows][:, None] * inc
