"""The physical-effect protocol.

An *effect* is something a real rig or drill string does that the base model of
the paper (eqs 11-12) lacks. Effects are small classes composed by
:class:`stiffnet.simulator.Simulator`; each one lives in its own module of this
package, like pysindy's feature libraries.

There are two kinds:

``DynamicsEffect``
    changes the equation of motion. The base right-hand side in relative
    coordinates (x: displacement of the mass relative to the shaker table,
    positive towards the restraint) is::

        v' = F(t) - 2 xi v - x - F_c(delta, delta') + sum(extra forces)
        F(t) = a w^2 sin(w t) + sum(effect.forcing_terms)        # base excitation
        delta = x - e(t) - y_r,  e(t) = e + sum(effect.gap_terms)  # penetration
        F_c = max(0, elastic(delta) + dissipation) if delta > 0     # never pulls

    Hooks that keep the model piecewise linear with sinusoidal forcing
    (``forcing_terms``, ``gap_terms``, ``contact_damping``) are solved in
    closed form; any other hook switches the simulator to the event-located
    numerical integrator.

``MeasurementEffect``
    acts on the sampled acceleration (the sensor chain, noise, the ADC).

Parameters are declared as a pydantic model (:class:`EffectParams`) whose
fields carry the physical default and the allowed range; a YAML value is either
a number or a ``[low, high]`` range sampled uniformly per trajectory. Hooks
receive ``p``, a dict of per-trajectory arrays of shape ``(B,)``.

Each effect also declares its *fit space* (:attr:`Effect.fit_space`, see
:mod:`stiffnet.effects.fit_space`): the parameters the measurement loop fits to a
campaign and their search ranges; its ``neutral`` values are "effect off".

A user effect is any subclass found at ``"package.module:ClassName"``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from stiffnet.effects.fit_space import FitSpace, default_fit_space
from stiffnet.errors import ConfigError

ParamArrays = dict[str, np.ndarray]
#: Annotation of every effect parameter: a number, or a ``[low, high]`` range.
ParamValue = float | list[float]


def param(
    default: float, ge: float, le: float, description: str, unit: str = "", integer: bool = False
) -> Any:
    """Declare an effect parameter with its physical default and allowed range.

    ``integer=True`` makes per-trajectory draws from a range whole numbers.
    """
    extra = {"ge": ge, "le": le, "unit": unit, "integer": integer}
    return Field(float(default), description=description, json_schema_extra=extra)


class EffectParams(BaseModel):
    """Base of every effect's parameter model: numbers or ``[low, high]`` ranges."""

    model_config = ConfigDict(extra="forbid")

    @model_validator(mode="before")
    @classmethod
    def _check_ranges(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        for name, value in data.items():
            field = cls.model_fields.get(name)
            if field is None:
                continue  # extra="forbid" reports it
            extra = field.json_schema_extra or {}
            lo, hi = extra.get("ge"), extra.get("le")
            values = value if isinstance(value, list | tuple) else [value]
            if isinstance(value, list | tuple) and (len(value) != 2 or value[0] > value[1]):
                raise ValueError(f"{name}: a range must be [low, high], got {value!r}")
            for v in values:
                if not isinstance(v, int | float | np.integer | np.floating) or isinstance(v, bool):
                    raise ValueError(f"{name}: expected a number or [low, high], got {v!r}")
                if lo is not None and hi is not None and not lo <= v <= hi:
                    raise ValueError(f"{name}={v} is outside the allowed range [{lo}, {hi}]")
        return data


class Effect:
    """Base of all effects. Subclasses set ``name``, ``kind`` and ``Params``."""

    name: ClassVar[str] = ""
    kind: ClassVar[str] = ""
    Params: ClassVar[type[EffectParams]] = EffectParams
    #: The effect's prior in the randomised training world (``configs/sim/default.yaml``,
    #: docs/priors.md): ``probability`` that a rig has it, ``params`` ranges and
    #: ``relative`` frequency draws (see :class:`stiffnet.config.sim.EffectSpec`);
    #: None when training rigs never have it.
    prior: ClassVar[dict[str, Any] | None] = None
    #: Parameters fitted to a campaign (None: every parameter with a declared range).
    fit_space: ClassVar[FitSpace | None] = None
    neutral: ClassVar[dict[str, float] | None] = None
    """Parameter values at which the effect does nothing (e.g. zero contact damping).

    Declared by dynamics effects that can be switched off row by row inside one
    batch (a randomised dataset where only some rigs have the effect; an effect
    without them is simulated separately for the rows that lack it), and used by
    the measurement loop as "effect off" (any effect)."""

    def __init__(self, **params: Any) -> None:
        try:
            self.params = self.Params(**params)
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(str(x) for x in first["loc"])
            msg = first["msg"].removeprefix("Value error, ")
            where = f" ({where})" if where and where not in msg else ""
            raise ConfigError(f"effect {self.name}{where}: {msg}") from None

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.params.model_dump().items())
        return f"{type(self).__name__}({args})"

    def batch_params(self, n: int, rng: np.random.Generator) -> ParamArrays:
        """Per-trajectory parameter arrays; ``[low, high]`` ranges are drawn uniformly."""
        out: ParamArrays = {}
        for name, value in self.params.model_dump().items():
            extra = type(self).Params.model_fields[name].json_schema_extra or {}
            if isinstance(value, list | tuple):
                if extra.get("integer"):
                    lo, hi = int(np.ceil(value[0])), int(np.floor(value[1]))
                    out[name] = rng.integers(lo, max(lo, hi) + 1, size=n) * 1.0
                else:
                    out[name] = rng.uniform(value[0], value[1], size=n)
            else:
                out[name] = np.full(n, float(value))
        return out

    @classmethod
    def campaign_fit_space(cls, fs_hz_min: float) -> FitSpace:
        """The fit space for a campaign whose lowest sampling rate is ``fs_hz_min``.

        Override when a range depends on the sampling rate (a sensor resonance
        must stay below Nyquist).
        """
        return (
            cls.fit_space if cls.fit_space is not None else default_fit_space(cls.parameter_table())
        )

    @classmethod
    def observed_fit_space(cls, space: FitSpace, observed: dict[str, float]) -> FitSpace:
        """The campaign's fit space adjusted to what the measurement shows (``observed``, as
        in :meth:`fit_seeds`: an identified sensor stage becomes a searched one). Default:
        unchanged."""
        return space

    @classmethod
    def fit_space_at(cls, params: Mapping[str, Any], fs_hz_min: float) -> FitSpace:
        """The fit space for a refit from ``params`` (a model's current values): the campaign
        space with every given parameter it does not fit held at its given value (never put
        back to the class default). Override to search around the given values."""
        space = cls.campaign_fit_space(fs_hz_min)
        fitted = set(space.fitted) | set(space.names)
        keep = {
            k: float(v)
            for k, v in params.items()
            if k not in fitted and isinstance(v, int | float) and not isinstance(v, bool)
        }
        return replace(space, fixed={**keep, **space.fixed}) if keep else space

    @classmethod
    def fit_seeds(cls, observed: dict[str, float], space: FitSpace) -> list[dict[str, float]]:
        """Data-driven starting points of a fit (effect parameters), from what the
        measurement shows (``observed``: e.g. ``ringing_hz``, the median post-impact ringing
        frequency in Hz). Default: none."""
        return []

    @classmethod
    def parameter_table(cls) -> list[dict[str, Any]]:
        """Name, default, range, unit and description of each parameter (for docs/CLI)."""
        rows = []
        for name, field in cls.Params.model_fields.items():
            extra = field.json_schema_extra or {}
            rows.append(
                {
                    "name": name,
                    "default": field.default,
                    "range": (extra.get("ge"), extra.get("le")),
                    "unit": extra.get("unit", ""),
                    "description": field.description or "",
                }
            )
        return rows


@dataclass
class Sinusoids:
    """A sum of sinusoids ``sum_j amp_j * sin(freq_j * t + phase_j)``, arrays ``(B, J)``."""

    amp: np.ndarray
    freq: np.ndarray
    phase: np.ndarray

    @classmethod
    def empty(cls, n: int) -> Sinusoids:
        z = np.zeros((n, 0))
        return cls(z, z.copy(), z.copy())

    def __add__(self, other: Sinusoids) -> Sinusoids:
        return Sinusoids(
            np.concatenate([self.amp, other.amp], axis=1),
            np.concatenate([self.freq, other.freq], axis=1),
            np.concatenate([self.phase, other.phase], axis=1),
        )

    def value(self, t: np.ndarray) -> np.ndarray:
        """Value at times ``t`` of shape ``(B,)``."""
        return np.sum(self.amp * np.sin(self.freq * t[:, None] + self.phase), axis=1)

    def rate(self, t: np.ndarray) -> np.ndarray:
        """Time derivative at times ``t`` of shape ``(B,)``."""
        return np.sum(self.amp * self.freq * np.cos(self.freq * t[:, None] + self.phase), axis=1)

    def subset(self, idx: np.ndarray) -> Sinusoids:
        return Sinusoids(self.amp[idx], self.freq[idx], self.phase[idx])


class DynamicsEffect(Effect):
    """An effect on the equation of motion (see the module docstring for the RHS).

    Override only the hooks you need. The three *closed-form hooks* keep the
    system piecewise linear; overriding any of the *numerical hooks* makes the
    simulator integrate numerically with event location.
    """

    kind = "dynamics"

    # ---- closed-form hooks (also used by the numerical integrator) ----
    def forcing_terms(self, p: ParamArrays, batch: Any) -> Sinusoids | None:
        """Extra base-excitation forcing (model units, added to a w^2 sin(w t))."""
        return None

    def gap_terms(self, p: ParamArrays, batch: Any) -> Sinusoids | None:
        """Variation of the gap with time, added to the nominal gap ``e``."""
        return None

    def contact_damping(self, p: ParamArrays, batch: Any) -> np.ndarray | None:
        """Linear viscous coefficient of the contact, force ``c * delta'``."""
        return None

    # ---- numerical hooks ----
    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray | None:
        """Elastic contact force for penetration ``delta >= 0`` (replaces ``beta*delta``)."""
        return None

    def contact_dissipation(
        self, delta: np.ndarray, rate: np.ndarray, p: ParamArrays, batch: Any
    ) -> np.ndarray | None:
        """Dissipative contact force that depends on the penetration (e.g. Hunt-Crossley
        ``lambda delta^n delta'``), added to the elastic force in contact (B,)."""
        return None

    def bound_elastic_contact(
        self, p: ParamArrays, batch: Any
    ) -> Callable[[np.ndarray], np.ndarray | None]:
        """:meth:`elastic_contact` with the rows' parameters fixed, ``f(delta)``: the engine
        binds it once per set of rows and calls it at every right-hand side. Override to
        decide once what the parameters make of the law (the same numbers)."""
        return lambda delta: self.elastic_contact(delta, p, batch)

    def bound_contact_dissipation(
        self, p: ParamArrays, batch: Any
    ) -> Callable[[np.ndarray, np.ndarray], np.ndarray | None] | None:
        """:meth:`contact_dissipation` with the rows' parameters fixed, ``f(delta, rate)``, or
        None where it is zero on every row (nothing added). Override as
        :meth:`bound_elastic_contact`."""
        return lambda delta, rate: self.contact_dissipation(delta, rate, p, batch)

    n_states: ClassVar[int] = 0
    """Number of extra state variables the effect integrates (e.g. a restraint's DOF)."""

    def initial_states(self, p: ParamArrays, batch: Any) -> np.ndarray:
        return np.zeros((len(batch), self.n_states))

    def restraint_position(self, s: np.ndarray, p: ParamArrays) -> np.ndarray | None:
        """Displacement of the restraint surface from the extra states ``s`` (B, n_states)."""
        return None

    def restraint_rate(self, s: np.ndarray, p: ParamArrays) -> np.ndarray | None:
        """Rate of :meth:`restraint_position` from the extra states ``s`` (B,), where it does
        not depend on the contact force (a mechanical DOF: its velocity state); None: the
        engine takes the position's change under the zero-force state derivative, one more
        :meth:`state_derivative` per right-hand side."""
        return None

    def state_derivative(
        self, t: np.ndarray, s: np.ndarray, contact_force: np.ndarray, p: ParamArrays
    ) -> np.ndarray:
        """d s / dt given the contact force acting on the restraint (B, n_states)."""
        raise NotImplementedError

    def extra_force(
        self,
        t: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        other: np.ndarray,
        mode: np.ndarray,
        p: ParamArrays,
    ) -> np.ndarray | None:
        """An additional force on the mass (e.g. friction).

        ``other`` is the sum of all other forces, ``mode`` the effect's discrete
        mode (0 by default), both (B,). Return None when the effect adds none.
        """
        return None

    def event_function(
        self,
        t: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        other: np.ndarray,
        mode: np.ndarray,
        p: ParamArrays,
    ) -> np.ndarray | None:
        """A function whose sign change switches the effect's mode (located exactly)."""
        return None

    def event_rate(
        self,
        t: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        accel: np.ndarray,
        other: np.ndarray,
        mode: np.ndarray,
        p: ParamArrays,
    ) -> np.ndarray | None:
        """Time derivative of :meth:`event_function` at the state, (B,), where the effect
        knows it from the state and ``accel`` (``dv/dt``, the mass's acceleration in the
        relative frame), NaN where not (e.g. a mode whose function reads ``other``'s rate).
        The engine then locates those rows' events by Newton steps from a Hermite guess
        (:func:`~stiffnet.simulator.events._newton`) instead of the secant. None: no rate
        known in any mode."""
        return None

    def next_mode(
        self, x: np.ndarray, v: np.ndarray, other: np.ndarray, mode: np.ndarray, p: ParamArrays
    ) -> np.ndarray:
        """The mode after the event function changed sign."""
        return mode

    @property
    def nonlinear_contact(self) -> bool:
        """True when the effect makes the contact force other than a linear spring plus a
        linear dashpot in the penetration (its own elastic or dissipative law): then an
        impact's shape depends on how hard the stop is hit, and a model must be trained at
        the impact speeds of the campaign it reads (:mod:`stiffnet.measurement.operating_points`).
        Default: whether the effect overrides :meth:`elastic_contact` or
        :meth:`contact_dissipation`; override when its parameters can make the law linear."""
        own = type(self)
        return any(
            getattr(own, h) is not getattr(DynamicsEffect, h)
            for h in ("elastic_contact", "contact_dissipation")
        )

    @property
    def closed_form(self) -> bool:
        """True when the effect only uses the closed-form hooks."""
        numerical = (
            "elastic_contact",
            "contact_dissipation",
            "restraint_position",
            "extra_force",
            "event_function",
        )
        own = type(self)
        return self.n_states == 0 and all(
            getattr(own, h) is getattr(DynamicsEffect, h) for h in numerical
        )


def batch_signal(signal: np.ndarray) -> np.ndarray:
    """A measurement effect's input as a float64 ``(B, N)`` array (checked)."""
    x = np.asarray(signal, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"signal must have shape (B, N), got {x.shape}")
    return x


def per_row(p: ParamArrays, key: str, n: int) -> np.ndarray:
    """Parameter ``key`` as a float64 array of one value per row."""
    return np.broadcast_to(np.asarray(p[key], dtype=np.float64), (n,))


class MeasurementEffect(Effect):
    """An effect on the recorded acceleration (sensor chain, noise, ADC)."""

    kind = "measurement"
    order: ClassVar[int] = 50
    """Place in the measurement chain, applied in increasing order whatever the YAML
    order: the sensor (10), then the baseline white noise (20, built in), other
    noise (30), user effects (50 by default) and last the converter (90)."""

    def apply(
        self, signal: np.ndarray, fs_hz: np.ndarray, p: ParamArrays, rng: np.random.Generator
    ) -> np.ndarray:
        """Transform sampled signals ``(B, N)``; ``fs_hz`` is the per-row rate in Hz.

        Signals are in the model's acceleration units. Besides the effect's own
        parameters, ``p`` holds per-row context: ``"_forcing_scale"`` (the
        forcing amplitude ``a w^2``, the paper's noise scale) and
        ``"_natural_frequency_hz"`` (f_n, to place physical frequencies).
        """
        raise NotImplementedError
