"""Lorenz-63 test signal: fixed-step RK4 in plain Python floats (fast, dependency-free).

Not a conftest on purpose: the benchmark imports it too.
"""

from __future__ import annotations

import numpy as np


def lorenz_x(
    n: int,
    dt: float = 0.01,
    transient: int = 1000,
    sigma: float = 10.0,
    rho: float = 28.0,
    beta: float = 8.0 / 3.0,
    state: tuple[float, float, float] = (1.0, 1.0, 1.0),
) -> np.ndarray:
    """x component of the Lorenz system, `n` samples every `dt` after `transient` steps."""

    def f(x: float, y: float, z: float) -> tuple[float, float, float]:
        return sigma * (y - x), x * (rho - z) - y, x * y - beta * z

    x, y, z = state
    out = np.empty(n)
    h = dt / 2
    for i in range(transient + n):
        k1 = f(x, y, z)
        k2 = f(x + h * k1[0], y + h * k1[1], z + h * k1[2])
        k3 = f(x + h * k2[0], y + h * k2[1], z + h * k2[2])
        k4 = f(x + dt * k3[0], y + dt * k3[1], z + dt * k3[2])
        x += dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        y += dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        z += dt / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
        if i >= transient:
            out[i - transient] = x
    return out
