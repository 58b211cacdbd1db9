"""Configuration of dataset simulation (``configs/sim/*.yaml``)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator

from stiffnet.config.window import WINDOW_PERIODS
from stiffnet.effects.registry import CANONICAL, build_effect
from stiffnet.geometry.calibration import DEFAULT_CLASSES, NO_CONTACT
from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ
from stiffnet.simulator.settings import SolverSettings


def _bounds(lo: float, hi: float, *, open_lo: bool = False):
    """A ``[low, high]`` pair inside the allowed domain [lo, hi]."""

    def check(v: tuple[float, float]) -> tuple[float, float]:
        a, b = v
        if a > b:
            raise ValueError(f"range must be [low, high], got [{a}, {b}]")
        if (a <= lo if open_lo else a < lo) or b > hi:
            left = "(" if open_lo else "["
            raise ValueError(f"[{a}, {b}] is outside the allowed range {left}{lo}, {hi}]")
        return v

    return Annotated[tuple[float, float], AfterValidator(check)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class SweepConfig(_Strict):
    """Parameter domain sampled for each trajectory (model units, paper eq. 12)."""

    beta: _bounds(0.0, 1000.0, open_lo=True) = (5.0, 100.0)
    beta_sampling: Literal["stratified", "uniform", "log_uniform"] = Field(
        "stratified", description="stratified: equal trajectories per class, uniform inside"
    )
    gap: _bounds(-2.0, 10.0) = (0.0, 3.0)
    amplitude: _bounds(0.0, 10.0, open_lo=True) = (0.2, 2.0)
    omega: _bounds(0.05, 5.0) = (0.8, 1.2)
    damping: _bounds(0.0, 0.5, open_lo=True) = (0.01, 0.05)
    noise: _bounds(0.0, 1.0) = Field(
        (0.0, 0.10), description="white noise std / (a w^2), drawn uniformly"
    )
    noise_levels: list[Annotated[float, Field(ge=0.0, le=1.0)]] | None = Field(
        None, description="discrete noise levels drawn with equal probability (overrides noise)"
    )
    fs_ratio: _bounds(8.0, 5000.0) = Field((50.0, 500.0), description="fs / f_n, log-uniform")
    natural_frequency_hz: float = Field(PAPER_NATURAL_FREQUENCY_HZ, gt=0.0, le=1e5)


class WindowConfig(_Strict):
    duration_periods: float = Field(
        float(WINDOW_PERIODS),
        ge=2.0,
        le=500.0,
        description="window length in natural periods (2 pi model time)",
    )
    per_trajectory: int = Field(4, ge=1, le=256, description="consecutive windows per trajectory")


class ClassSpec(_Strict):
    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_\-]+$")
    beta: tuple[float, float]


def default_classes() -> list[ClassSpec]:
    """The shipped stiffness classes (:data:`stiffnet.geometry.calibration.DEFAULT_CLASSES`)."""
    return [ClassSpec(name=name, beta=(lo, hi)) for name, lo, hi in DEFAULT_CLASSES]


class RelativeParam(_Strict):
    """A frequency parameter drawn per trajectory in units of that trajectory's f_n or fs.

    A rig's sensor and filters sit at frequencies that only mean something relative
    to the rig (``natural_frequency``: the mounted resonance well above f_n) or to
    the acquisition (``sampling_rate``: an anti-alias corner at a fraction of fs).
    """

    per: Literal["natural_frequency", "sampling_rate"]
    range: _bounds(0.0, 1e6, open_lo=True)
    scale: Literal["linear", "log"] = Field("log", description="uniform in the value or its log")


class EffectSpec(_Strict):
    """One physical effect of the simulated rigs, with its per-trajectory priors.

    ``params`` are numbers or ``[low, high]`` ranges drawn uniformly per trajectory;
    ``relative`` draws frequency parameters (unit Hz) relative to f_n or fs;
    ``probability`` is the fraction of trajectories that have the effect at all
    (the others are simulated without it), which is how a randomised training
    world keeps ideal rigs in its mix.
    """

    name: str
    probability: float = Field(1.0, ge=0.0, le=1.0, description="fraction of trajectories")
    params: dict[str, float | list[float]] = Field(default_factory=dict)
    relative: dict[str, RelativeParam] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _valid_effect(self) -> EffectSpec:
        # A shipped effect is checked here; a user ``module:Class`` imports (runs) code,
        # so SimulationConfig checks it only after every other field has passed.
        if not self.is_user_code:
            self.check()
        return self

    def check(self) -> None:
        """Build the effect (its parameters) and check the relative draws name frequencies."""
        effect = build_effect(self.name, self.params)  # raises ConfigError naming the problem
        fields = type(effect).Params.model_fields
        for key in self.relative:
            if key not in fields:
                raise ValueError(f"effect {self.name}: relative parameter {key!r} is not one of "
                                 f"its parameters ({', '.join(fields)})")  # fmt: skip
            if (fields[key].json_schema_extra or {}).get("unit") != "Hz":
                raise ValueError(
                    f"effect {self.name}: relative parameter {key!r} is not a frequency in Hz"
                )
            if key in self.params:
                raise ValueError(f"effect {self.name}: {key!r} is given both in params and "
                                 "relative")  # fmt: skip

    @property
    def is_user_code(self) -> bool:
        """A ``module:Class`` effect: validating it imports that module (configs are code)."""
        return self.name not in CANONICAL

    def build(self) -> Any:
        return build_effect(self.name, self.params)


def randomised_effects() -> list[EffectSpec]:
    """The training world's nuisance effects: every library effect's own ``prior``.

    ``configs/sim/default.yaml`` restates this list (a test checks it); the
    model's default ``effects`` stay empty, the ideal base model of eqs 11-12.
    """
    from stiffnet.effects.registry import CANONICAL, effect_class

    return [
        EffectSpec(name=name, **effect_class(name).prior)
        for name in CANONICAL
        if effect_class(name).prior is not None
    ]


class SolverConfig(SolverSettings):
    """The simulator's settings (defaults and ranges from
    :class:`~stiffnet.simulator.settings.SolverSettings`) and the batch size of a dataset."""

    batch_size: int = Field(256, ge=1, le=65536, description="trajectories simulated together")


class SimulationConfig(_Strict):
    """Everything ``stiffnet simulate`` needs; defaults are the shipped domain."""

    seed: int = Field(0, ge=0)
    n_trajectories: int = Field(2000, ge=1, le=10_000_000)
    shard_size: int = Field(512, ge=1, le=1_000_000, description="trajectories per shard")
    sweep: SweepConfig = Field(default_factory=SweepConfig)
    windows: WindowConfig = Field(default_factory=WindowConfig)
    classes: list[ClassSpec] = Field(default_factory=default_classes, min_length=1)
    no_contact_class: str = NO_CONTACT
    effects: list[EffectSpec] = Field(default_factory=list)
    ideal_fraction: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="fraction of trajectories simulated without any effect (ideal rigs)",
    )
    solver: SolverConfig = Field(default_factory=SolverConfig)

    @model_validator(mode="after")
    def _classes_tile_beta(self) -> SimulationConfig:
        names = [c.name for c in self.classes] + [self.no_contact_class]
        if len(set(names)) != len(names):
            raise ValueError("class names must be unique (no_contact_class included)")
        for prev, cur in zip(self.classes, self.classes[1:], strict=False):
            if cur.beta[0] != prev.beta[1]:
                raise ValueError(
                    f"classes must tile beta without gaps or overlaps: {prev.name} ends at "
                    f"{prev.beta[1]} but {cur.name} starts at {cur.beta[0]}"
                )
        for c in self.classes:
            if c.beta[0] >= c.beta[1]:
                raise ValueError(f"class {c.name}: beta range must be [low, high] with low < high")
        lo, hi = self.classes[0].beta[0], self.classes[-1].beta[1]
        if self.sweep.beta[0] < lo or self.sweep.beta[1] > hi:
            raise ValueError(
                f"sweep.beta {list(self.sweep.beta)} is not covered by the classes [{lo}, {hi}]"
            )
        names = [e.name for e in self.effects]
        if len(set(names)) != len(names):
            raise ValueError("an effect is listed twice")
        for e in self.effects:  # last: everything else is valid, now import user code
            if e.is_user_code:
                e.check()
            self._check_relative(e)
        return self

    def _check_relative(self, spec: EffectSpec) -> None:
        """Relative frequency draws must land inside the effect's allowed range."""
        fields = spec.build().Params.model_fields
        fn = self.sweep.natural_frequency_hz
        for key, rel in spec.relative.items():
            extra = fields[key].json_schema_extra or {}
            if rel.per == "natural_frequency":
                lo, hi = rel.range[0] * fn, rel.range[1] * fn
            else:
                lo, hi = (
                    rel.range[0] * fn * self.sweep.fs_ratio[0],
                    rel.range[1] * fn * (self.sweep.fs_ratio[1]),
                )
            if lo < extra.get("ge", -np.inf) or hi > extra.get("le", np.inf):
                raise ValueError(
                    f"effect {spec.name}: {key} relative to the {rel.per.replace('_', ' ')} "
                    f"{list(rel.range)} gives {lo:.4g}-{hi:.4g} Hz, outside the allowed range "
                    f"[{extra.get('ge')}, {extra.get('le')}] Hz"
                )

    def class_names(self) -> list[str]:
        """All labels, no-contact first (its index is 0)."""
        return [self.no_contact_class] + [c.name for c in self.classes]
