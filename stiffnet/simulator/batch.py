"""Parameter sets of the impact oscillator, batched."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from stiffnet.errors import ConfigError

#: The paper's natural frequency (section 5.2.1), used where none is given.
PAPER_NATURAL_FREQUENCY_HZ = 9.48


@dataclass
class OscillatorBatch:
    """B parameter sets of eqs (11)-(12), each field an array of shape ``(B,)``.

    Attributes
    ----------
    beta : stiffness ratio of the restraint to the primary spring.
    gap : gap ``e`` between the mass at rest and the restraint (model units).
    amplitude : base-excitation amplitude ``a`` (forcing ``a w^2 sin(w t)``).
    omega : forcing frequency ratio ``w = f / f_n``.
    damping : damping ratio ``xi``.
    natural_frequency_hz : ``f_n``; only physical units (Hz, seconds) depend on it.
    """

    beta: np.ndarray
    gap: np.ndarray
    amplitude: np.ndarray
    omega: np.ndarray
    damping: np.ndarray
    natural_frequency_hz: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = None
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None:
                continue
            arr = np.atleast_1d(np.asarray(value, dtype=float))
            if arr.ndim != 1:
                raise ConfigError(f"{f.name} must be a 1-D array of parameter values")
            if n is None:
                n = arr.size
            elif arr.size == 1:
                arr = np.full(n, arr[0])
            elif arr.size != n:
                raise ConfigError(f"{f.name} has {arr.size} values, expected {n}")
            if not np.all(np.isfinite(arr)):
                raise ConfigError(f"{f.name} contains NaN or infinite values")
            setattr(self, f.name, arr)
        if self.natural_frequency_hz is None:
            self.natural_frequency_hz = np.full(n, PAPER_NATURAL_FREQUENCY_HZ)
        checks = (
            ("beta", self.beta >= 0, ">= 0"),
            ("amplitude", self.amplitude >= 0, ">= 0"),
            ("omega", self.omega > 0, "> 0"),
            ("damping", (self.damping > 0) & (self.damping < 1), "in (0, 1)"),
        )
        for name, ok, rule in checks:
            if not np.all(ok):
                raise ConfigError(f"{name} must be {rule}")
        if np.any(self.natural_frequency_hz <= 0):
            raise ConfigError("natural_frequency_hz must be positive")

    def __len__(self) -> int:
        return self.beta.size

    @property
    def forcing_scale(self) -> np.ndarray:
        """``a w^2``: the forcing amplitude, the paper's noise scale."""
        return self.amplitude * self.omega**2

    def subset(self, idx: np.ndarray) -> OscillatorBatch:
        return OscillatorBatch(**{f.name: getattr(self, f.name)[idx] for f in fields(self)})

    @classmethod
    def single(
        cls,
        beta: float,
        gap: float,
        amplitude: float,
        omega: float,
        damping: float,
        natural_frequency_hz: float = PAPER_NATURAL_FREQUENCY_HZ,
    ) -> OscillatorBatch:
        """A batch of one parameter set."""
        return cls(
            np.array([beta]),
            np.array([gap]),
            np.array([amplitude]),
            np.array([omega]),
            np.array([damping]),
            np.array([natural_frequency_hz]),
        )
