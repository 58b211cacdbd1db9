"""The simulator: the base model of eqs (11)-(12) composed with physical effects."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from pydantic import ValidationError

from stiffnet.effects.base import (
    DynamicsEffect,
    Effect,
    MeasurementEffect,
    ParamArrays,
    Sinusoids,
)
from stiffnet.errors import ConfigError
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.linear import LinearModel
from stiffnet.simulator.motion_cache import motion, motion_key
from stiffnet.simulator.numerical import simulate_numerical
from stiffnet.simulator.settings import SolverSettings

#: Internal steps never exceed this fraction of the contact's natural period / pi,
#: so the switching function has at most one extremum per step.
_CONTACT_STEP_FACTOR = 1.5
_WHITE_NOISE_ORDER = 20
#: The measurement chain's white noise comes after the effects of lower ``order``.
WHITE_NOISE_ORDER = _WHITE_NOISE_ORDER
#: A warm start's numerical stretch lasts at least this many forcing periods: the effects'
#: extra states start at rest and their discrete modes at the stretch's first event.
WARM_MIN_PERIODS = 4.0


@dataclass
class SimulationResult:
    """Sampled trajectories of a batch, shape ``(B, N)`` each.

    ``accel`` is what the accelerometer records (measurement chain and noise
    applied); ``clean_accel`` the absolute acceleration of the mass itself.
    Model time: sample ``n`` of row ``b`` is at ``t0[b] + n * 2 pi / fs_ratio[b]``;
    physical seconds divide model time by ``2 pi f_n``.
    """

    batch: OscillatorBatch
    fs_ratio: np.ndarray
    accel: np.ndarray
    clean_accel: np.ndarray
    x: np.ndarray
    v: np.ndarray
    contact_force: np.ndarray
    impacts: np.ndarray
    t0: np.ndarray
    noise: np.ndarray
    engine: str
    effect_params: dict[str, ParamArrays] = field(default_factory=dict)

    @property
    def fs_hz(self) -> np.ndarray:
        return self.fs_ratio * self.batch.natural_frequency_hz

    @property
    def in_contact(self) -> np.ndarray:
        """True where the mass touches the restraint at the sample."""
        return self.contact_force > 0


@dataclass
class RowDraws:
    """What a simulation draws before its motion: initial states (B,), every effect's
    parameters (after the activity masks' neutral values) and the masks by effect name."""

    x0: np.ndarray
    v0: np.ndarray
    params: dict[str, ParamArrays]
    masks: dict[str, np.ndarray]


class Simulator:
    """Impact oscillator with a list of effects (the parts it is given).

    Parameters
    ----------
    effects : dynamics and measurement effects, in any order.
    settings : the solver settings (:class:`~stiffnet.simulator.settings.SolverSettings`:
        transient rule and RK4 substeps); default: that model's defaults.
    **overrides : fields of ``settings`` to change (``settle_tolerance=1e-2``...),
        validated by the same model.

    The closed-form engine (:mod:`stiffnet.simulator.compiled`) runs the rows on
    numba's threads; :func:`~stiffnet.simulator.compiled.limited_threads` bounds them.
    """

    def __init__(
        self,
        effects: Sequence[Effect] = (),
        settings: SolverSettings | None = None,
        **overrides: float,
    ) -> None:
        base = SolverSettings() if settings is None else settings.solver_settings()
        try:
            self.settings = SolverSettings(**{**base.model_dump(), **overrides})
        except ValidationError as exc:
            err = exc.errors()[0]
            where = ".".join(str(x) for x in err["loc"])
            raise ConfigError(f"solver setting {where}: {err['msg']}") from None
        self.effects = list(effects)
        names = [e.name for e in self.effects]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ConfigError(f"effect listed twice: {', '.join(sorted(dup))}")
        self.dynamics = [e for e in self.effects if isinstance(e, DynamicsEffect)]
        self.measurement = sorted(
            (e for e in self.effects if isinstance(e, MeasurementEffect)), key=lambda e: e.order
        )
        self.settle_tolerance = self.settings.settle_tolerance
        self.min_transient_periods = self.settings.min_transient_periods
        self.substeps = self.settings.substeps

    @property
    def engine(self) -> str:
        """``closed_form`` when every effect keeps the model piecewise linear."""
        return "closed_form" if all(e.closed_form for e in self.dynamics) else "numerical"

    def transient_time(self, batch: OscillatorBatch) -> np.ndarray:
        settle = -np.log(self.settle_tolerance) / batch.damping
        return np.maximum(settle, self.min_transient_periods * 2 * np.pi / batch.omega)

    def transient_split(self, batch: OscillatorBatch, t_tr: np.ndarray) -> np.ndarray:
        """Where a warm start hands the transient to the numerical engine, per row (B,).

        The closed form settles the random initial state onto the orbit of the
        piecewise-linear model; what is left is the difference between that orbit and
        the numerical effects' one, ``warm_start`` of the orbit at most (the effects'
        size, not the initial state's), and free oscillations decay as ``exp(-xi t)``:
        the numerical engine needs ``ln(warm_start / settle_tolerance) / xi`` of the
        transient, and at least :data:`WARM_MIN_PERIODS` forcing periods. 0 for every
        row on a cold start (``warm_start`` 0) or where that stretch is the whole
        transient.
        """
        eps = self.settings.warm_start
        if eps <= 0:
            return np.zeros(len(batch))
        stretch = np.maximum(
            np.log(max(eps / self.settle_tolerance, 1.0)) / batch.damping,
            WARM_MIN_PERIODS * 2 * np.pi / batch.omega,
        )
        return np.maximum(t_tr - stretch, 0.0)

    def simulate(
        self,
        batch: OscillatorBatch,
        fs_ratio: np.ndarray | float,
        n_samples: int,
        noise: np.ndarray | float = 0.0,
        rng: np.random.Generator | int | None = None,
        x0: np.ndarray | None = None,
        v0: np.ndarray | None = None,
        effect_params: dict[str, ParamArrays] | None = None,
        active: dict[str, np.ndarray] | None = None,
        row_samples: np.ndarray | None = None,
    ) -> SimulationResult:
        """Simulate ``n_samples`` of each parameter set after its transient.

        Parameters
        ----------
        fs_ratio : sampling rate over natural frequency, ``fs / f_n`` (per row).
        noise : white-noise standard deviation as a fraction of ``a w^2`` (per row).
        rng : generator or seed for initial conditions, ranged effect parameters,
            noise and measurement effects.
        x0, v0 : initial state; default uniform in ``[-a, a]`` and ``[-a w, a w]``.
        effect_params : per-trajectory parameters by effect name, to override draws.
        active : per-trajectory booleans by effect name: rows where the effect is off are
            simulated without it (a dynamics effect through its ``neutral`` parameters, a
            measurement effect by skipping those rows). Default: on everywhere.
        row_samples : the samples each row needs (B,), when fewer than ``n_samples``: the
            numerical engine then integrates each row at its own rate and stops a row at its
            own count (:func:`~stiffnet.simulator.numerical.recording_substeps`); a row's
            later samples are not simulated (noise only). Default: every row needs all.
        """
        b = len(batch)
        if n_samples < 1:
            raise ConfigError("n_samples must be >= 1")
        fs_ratio = np.broadcast_to(np.asarray(fs_ratio, float), (b,)).copy()
        noise = np.broadcast_to(np.asarray(noise, float), (b,)).copy()
        if np.any(fs_ratio < 4):
            raise ConfigError("fs_ratio (fs / f_n) must be >= 4")
        if np.any(noise < 0):
            raise ConfigError("noise must be >= 0")
        rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        draws = self.draw_inputs(batch, rng, x0, v0, effect_params, active)
        out = self.motion_of(batch, fs_ratio, n_samples, draws, row_samples)
        measured = self.measure(out.accel, batch, fs_ratio, noise, draws, rng, row_samples)
        return SimulationResult(
            batch=batch, fs_ratio=fs_ratio, accel=measured, clean_accel=out.accel,
            x=out.x, v=out.v, contact_force=out.contact_force, impacts=out.impacts,
            t0=out.t0, noise=noise, engine=self.engine, effect_params=draws.params,
        )  # fmt: skip

    def draw_inputs(
        self,
        batch: OscillatorBatch,
        rng: np.random.Generator,
        x0: np.ndarray | None = None,
        v0: np.ndarray | None = None,
        effect_params: dict[str, ParamArrays] | None = None,
        active: dict[str, np.ndarray] | None = None,
    ) -> RowDraws:
        """What :meth:`simulate` draws from ``rng`` before the motion (same order).

        The motion (:meth:`motion_of`) draws nothing and the measurement chain
        (:meth:`measure`) draws after it, so a caller may compute the motion of rows drawn
        by several generators together and measure each group from its own generator.
        """
        b = len(batch)
        if x0 is None:
            x0 = rng.uniform(-1, 1, b) * batch.amplitude
        if v0 is None:
            v0 = rng.uniform(-1, 1, b) * batch.amplitude * batch.omega
        params = {e.name: e.batch_params(b, rng) for e in self.effects}
        for name, given in (effect_params or {}).items():
            if name not in params:
                raise ConfigError(f"parameters given for effect {name!r} that is not enabled")
            params[name].update({k: np.asarray(v, float) for k, v in given.items()})
        masks = self._activity(active, params, b)
        return RowDraws(x0, v0, params, masks)

    def motion_of(
        self,
        batch: OscillatorBatch,
        fs_ratio: np.ndarray,
        n_samples: int,
        draws: RowDraws,
        row_samples: np.ndarray | None = None,
    ) -> Any:
        """The engine's output for ``draws`` (``EngineResult``), before the measurement chain.

        Deterministic; with the numerical engine a row's motion depends on the batch it
        runs in by the integrator's error (the transient's step count and the substeps
        are the batch's).
        """
        h = 2 * np.pi / fs_ratio
        t_tr = self.transient_time(batch)
        x0, v0, params = draws.x0, draws.v0, draws.params
        return motion(
            lambda: self._motion_key(batch, params, x0, v0, t_tr, h, row_samples),
            lambda: self._motion(batch, params, x0, v0, t_tr, h, n_samples, row_samples),
            n_samples,
            _first_samples,
        )

    def measure(
        self,
        accel: np.ndarray,
        batch: OscillatorBatch,
        fs_ratio: np.ndarray,
        noise: np.ndarray,
        draws: RowDraws,
        rng: np.random.Generator,
        row_samples: np.ndarray | None = None,
    ) -> np.ndarray:
        """The measurement chain and white noise on ``accel`` (B, N), drawn from ``rng``
        (``row_samples``: the samples each row needs, as :meth:`simulate`'s; a filter may
        leave a row's later samples unfiltered)."""
        return self._measure(
            accel, batch, fs_ratio, noise, draws.params, rng, draws.masks, row_samples
        )

    def _motion(self, batch, params, x0, v0, t_tr, h, n_samples, row_samples=None) -> Any:
        """The engine's output: the motion sampled, before the measurement chain."""
        if self.engine == "closed_form":
            # imported here: numba's import (~0.25 s) is paid by simulating, not by
            # every module that builds a Simulator or reads its results
            from stiffnet.simulator.compiled import simulate_closed_form

            model = self.linear_model(batch, params)
            return simulate_closed_form(model, x0, v0, t_tr, h, n_samples, row_samples=row_samples)
        t_w = self.transient_split(batch, t_tr)
        if np.any(t_w > 0):  # warm start: the closed form's state at t_w starts the RK4
            from stiffnet.simulator.compiled import simulate_closed_form

            warm = simulate_closed_form(self.linear_model(batch, params), x0, v0, t_w, h, 1)
            x0 = np.where(t_w > 0, warm.x[:, 0], x0)
            v0 = np.where(t_w > 0, warm.v[:, 0], v0)
        # RK4 marches on a uniform grid: transient steps as short as the contact's.
        h_cap = np.minimum(2 * np.pi / 40, _CONTACT_STEP_FACTOR / np.sqrt(1 + batch.beta))
        n_tr = int(np.ceil(np.max((t_tr - t_w) / h_cap)))
        return simulate_numerical(
            batch, self.dynamics, [params[e.name] for e in self.dynamics],
            x0, v0, (t_tr - t_w - h) / n_tr, n_tr, h, n_samples, substeps=self.substeps,
            row_samples=row_samples, oversampled=self.settings.oversampled, t_start=t_w,
            record_as_transient=self.settings.record_substeps == "transient",
        )  # fmt: skip

    def _motion_key(self, batch, params, x0, v0, t_tr, h, row_samples=None) -> bytes:
        """What the motion depends on (:mod:`stiffnet.simulator.motion_cache`)."""
        dyn = [
            (
                type(e).__module__,
                type(e).__qualname__,
                repr(getattr(e, "params", None)),
                params[e.name],
            )
            for e in self.dynamics
        ]
        fields = [getattr(batch, f) for f in ("beta", "gap", "amplitude", "omega", "damping")]
        return motion_key(
            self.engine, dyn, fields, batch.natural_frequency_hz, x0, v0, t_tr, h, self.substeps,
            row_samples,  # rows stop at their own length, each at its own substeps
            *([self.settings.oversampled] if self.engine == "numerical" else []),
            # a warm start's motion differs from a cold one's (by the orbits' difference)
            *([self.settings.warm_start] if self._warm else []),
            # the record integrated at the transient's substep moves by RK4's error there
            *(["record:transient"] if self._record_as_transient else []),
        )  # fmt: skip

    @property
    def _warm(self) -> bool:
        """Whether the numerical engine starts warm (the motion then depends on it)."""
        return self.engine == "numerical" and self.settings.warm_start > 0

    @property
    def _record_as_transient(self) -> bool:
        """Whether the numerical engine integrates the record at the transient's substep."""
        return self.engine == "numerical" and self.settings.record_substeps == "transient"

    def linear_model(self, batch: OscillatorBatch, params: dict[str, ParamArrays]) -> LinearModel:
        """The piecewise-linear model (closed-form hooks of every dynamics effect)."""
        b = len(batch)
        forcing = Sinusoids(
            (batch.amplitude * batch.omega**2)[:, None], batch.omega[:, None], np.zeros((b, 1))
        )
        gap = Sinusoids.empty(b)
        damping = np.zeros(b)
        for eff in self.dynamics:
            p = params[eff.name]
            if (f := eff.forcing_terms(p, batch)) is not None:
                forcing = forcing + f
            if (g := eff.gap_terms(p, batch)) is not None:
                gap = gap + g
            if (c := eff.contact_damping(p, batch)) is not None:
                damping = damping + c
        return LinearModel(batch, forcing, gap, damping)

    def _activity(
        self, active: dict[str, np.ndarray] | None, params: dict[str, ParamArrays], b: int
    ) -> dict[str, np.ndarray]:
        """Check the per-row masks; switch dynamics effects off through their neutral values."""
        masks: dict[str, np.ndarray] = {}
        for name, mask in (active or {}).items():
            eff = next((e for e in self.effects if e.name == name), None)
            if eff is None:
                raise ConfigError(f"activity given for effect {name!r} that is not enabled")
            mask = np.broadcast_to(np.asarray(mask, dtype=bool), (b,))
            if mask.all():
                continue
            if isinstance(eff, DynamicsEffect):
                if eff.neutral is None:
                    raise ConfigError(
                        f"effect {name} declares no neutral parameters, so it cannot be off "
                        "for some rows of a batch: simulate those rows without it"
                    )
                p = params[name]
                for key, value in eff.neutral.items():
                    p[key] = np.where(mask, np.broadcast_to(p[key], (b,)), value)
            masks[name] = mask
        return masks

    def _measure(
        self, accel, batch, fs_ratio, noise, params, rng, masks=None, row_samples=None
    ) -> np.ndarray:
        """The measurement chain, in physical order, with the baseline white noise."""
        fs_hz = fs_ratio * batch.natural_frequency_hz
        context = {
            "_forcing_scale": batch.forcing_scale,
            "_natural_frequency_hz": batch.natural_frequency_hz,
        }
        if row_samples is not None:  # a causal filter need not run past a row's own samples
            context["_row_samples"] = np.broadcast_to(np.asarray(row_samples), (len(batch),))
        signal = accel
        white_done = False
        for eff in self.measurement:
            if not white_done and eff.order > _WHITE_NOISE_ORDER:
                signal = self._white(signal, batch, noise, rng)
                white_done = True
            p = {**params[eff.name], **context}
            mask = (masks or {}).get(eff.name)
            if mask is None:
                signal = eff.apply(signal, fs_hz, p, rng)
            elif mask.any():  # the effect acts on its rows only
                rows = np.flatnonzero(mask)
                sub = {k: np.broadcast_to(v, (len(mask),))[rows] for k, v in p.items()}
                signal = np.array(signal, dtype=np.float64, copy=True)
                signal[rows] = eff.apply(signal[rows], fs_hz[rows], sub, rng)
        if not white_done:
            signal = self._white(signal, batch, noise, rng)
        return signal

    @staticmethod
    def _white(signal, batch, noise, rng) -> np.ndarray:
        if not np.any(noise):
            return signal
        std = noise * batch.forcing_scale
        return signal + rng.standard_normal(signal.shape) * std[:, None]


def _first_samples(out: Any, n: int) -> Any:
    """The first ``n`` samples of an engine's output (``EngineResult``)."""
    fields = ("x", "v", "accel", "contact_force", "impacts")
    return replace(out, **{f: getattr(out, f)[:, :n] for f in fields})
