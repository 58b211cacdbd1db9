"""Draw trajectory parameters over the configured domain."""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from stiffnet.config.sim import SimulationConfig
from stiffnet.simulator.batch import OscillatorBatch


@dataclass
class TrajectoryPlan:
    """Parameters of the trajectories of one shard.

    ``effect_params`` holds every configured effect's per-trajectory parameters and
    ``active`` whether the trajectory has the effect at all (its ``probability``).
    """

    batch: OscillatorBatch
    fs_ratio: np.ndarray
    noise: np.ndarray
    window_samples: np.ndarray  # samples per window, per trajectory
    effect_params: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    active: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.batch)

    def subset(self, idx: np.ndarray) -> TrajectoryPlan:
        return TrajectoryPlan(
            self.batch.subset(idx),
            self.fs_ratio[idx],
            self.noise[idx],
            self.window_samples[idx],
            {e: {k: v[idx] for k, v in p.items()} for e, p in self.effect_params.items()},
            {e: m[idx] for e, m in self.active.items()},
        )

    @classmethod
    def concatenate(cls, plans: list[TrajectoryPlan]) -> TrajectoryPlan:
        """The plans' rows one after the other (plans of configs with the same effects)."""
        first = plans[0]
        cat = np.concatenate
        return cls(
            OscillatorBatch(
                *(
                    cat([np.broadcast_to(getattr(p.batch, f.name), (len(p),)) for p in plans])
                    for f in fields(OscillatorBatch)
                )
            ),  # fmt: skip
            cat([p.fs_ratio for p in plans]),
            cat([p.noise for p in plans]),
            cat([p.window_samples for p in plans]),
            {
                e: {k: cat([p.effect_params[e][k] for p in plans]) for k in v}
                for e, v in first.effect_params.items()
            },  # fmt: skip
            {e: cat([p.active[e] for p in plans]) for e in first.active},
        )


def _beta(cfg: SimulationConfig, n: int, rng: np.random.Generator) -> np.ndarray:
    lo, hi = cfg.sweep.beta
    mode = cfg.sweep.beta_sampling
    if mode == "uniform":
        return rng.uniform(lo, hi, n)
    if mode == "log_uniform":
        return np.exp(rng.uniform(np.log(lo), np.log(hi), n))
    # stratified: the same number of trajectories in each class met by the sweep,
    # uniform within the class; balance matters more to classifiers than density.
    ranges = [
        (max(lo, c.beta[0]), min(hi, c.beta[1])) for c in cfg.classes if c.beta[1] > lo and
        c.beta[0] < hi
    ]  # fmt: skip
    which = rng.permutation(np.arange(n) % len(ranges))
    a = np.array([r[0] for r in ranges])[which]
    b = np.array([r[1] for r in ranges])[which]
    return rng.uniform(a, b)


def sample_plan(cfg: SimulationConfig, n: int, rng: np.random.Generator) -> TrajectoryPlan:
    """Draw ``n`` trajectories: beta as configured, the rest uniform (fs log-uniform)."""
    sw = cfg.sweep
    beta = _beta(cfg, n, rng)
    gap = rng.uniform(*sw.gap, n)
    amplitude = rng.uniform(*sw.amplitude, n)
    omega = rng.uniform(*sw.omega, n)
    damping = rng.uniform(*sw.damping, n)
    fs_ratio = np.exp(rng.uniform(np.log(sw.fs_ratio[0]), np.log(sw.fs_ratio[1]), n))
    if sw.noise_levels:
        noise = rng.choice(np.asarray(sw.noise_levels, float), n)
    else:
        noise = rng.uniform(*sw.noise, n)
    batch = OscillatorBatch(
        beta, gap, amplitude, omega, damping, np.full(n, sw.natural_frequency_hz)
    )
    window = np.maximum(8, np.round(cfg.windows.duration_periods * fs_ratio)).astype(int)
    params, active = _effect_draws(cfg, batch, fs_ratio, rng)
    return TrajectoryPlan(batch, fs_ratio, noise, window, params, active)


def _effect_draws(
    cfg: SimulationConfig, batch: OscillatorBatch, fs_ratio: np.ndarray, rng: np.random.Generator
) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, np.ndarray]]:
    """Each effect's per-trajectory parameters (its priors) and whether the rig has it."""
    n = len(batch)
    params: dict[str, dict[str, np.ndarray]] = {}
    active: dict[str, np.ndarray] = {}
    # ideal rigs keep the paper's world in the mix however many effects are configured
    ideal = rng.random(n) < cfg.ideal_fraction if cfg.effects else np.zeros(n, bool)
    for spec in cfg.effects:
        effect = spec.build()  # keyed by the effect's own name, as the simulator keys it
        p = effect.batch_params(n, rng)
        for key, rel in spec.relative.items():
            lo, hi = rel.range
            if rel.scale == "log":
                r = np.exp(rng.uniform(np.log(lo), np.log(hi), n))
            else:
                r = rng.uniform(lo, hi, n)
            unit = batch.natural_frequency_hz
            if rel.per == "sampling_rate":
                unit = unit * fs_ratio
            p[key] = r * unit
        params[effect.name] = p
        active[effect.name] = (rng.random(n) < spec.probability) & ~ideal
    return params, active
