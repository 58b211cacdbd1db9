"""Each recording's beta by simulation: the least discrepancy over beta at its operating point.

A learned model reads beta from standardised windows; where two betas give windows that
look alike to it (a soft first stage pushed into a stiffer second one, near a class edge)
it can be wrong while the physics still tells them apart. This reading asks the physics
directly: every recording with a full operating point in its manifest (gap, amplitude,
frequency ratio, damping ratio) is simulated with the given effects (the loop's current
law and nuisances) at a grid of betas, and compared with the recording by the
phase-independent statistics of :mod:`stiffnet.measurement.discrepancy`. Its beta is where
the discrepancy ``D(beta)`` is least.

The profile is built in two simulated batches (every row at every beta at once):

1. a **coarse grid** of :attr:`SimulatedBetaConfig.coarse_points` log-spaced betas over
   :attr:`SimulatedBetaConfig.beta_range`;
2. a **local refinement**: :attr:`SimulatedBetaConfig.refine_per_side` betas on each side of
   each row's coarse minimum, evenly in log beta up to its neighbours;

the estimate is the vertex of the parabola in log beta through the least point of the
profile and its two neighbours (kept within them).

**Interval** (the profile against the recording's own noise floor ``f``,
:mod:`stiffnet.measurement.noise_floor`, split-half repeatability at the simulated
length): the connected range of betas around the minimum where

    D(beta) <= D_min + rise * max(f, D_min)

(linear interpolation in log beta between profile points; open at the grid's edge). A
model at the floor scatters by about one floor, so a rise of ``rise`` floors is the
profile's tolerance; where the best beta does not bring the recording to its floor, the
law is approximate and its misfit ``D_min`` scales the tolerance instead (a profile
likelihood whose scale is estimated from the residual).

**Reproduction**: the recording is *reproduced* when ``D_min <= reproduce_factor * f_r``,
``f_r`` its floor but at most the non-repeatable limit
(:data:`~stiffnet.measurement.noise_floor.NON_REPEATABLE_FACTOR` times the campaign's median
floor: a wandering recording's own floor is one draw, and a match within it does not pin
beta);
otherwise no beta of the given physics reproduces it (a non-repeatable orbit, physics the
model lacks) and the reading says so instead of trusting its minimum.

The class is the beta's (:func:`stiffnet.geometry.calibration.beta_class`); a recording
without impacts has none to read (``no_contact``, no beta).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from stiffnet.campaign import Campaign, ManifestRow
from stiffnet.campaign.simulate import DEFAULT_SEED, CampaignSolverSettings, simulate_rows
from stiffnet.effects.base import Effect
from stiffnet.geometry.calibration import NO_CONTACT, beta_class
from stiffnet.measurement.discrepancy import normalised_differences, recording_discrepancy
from stiffnet.measurement.noise_floor import NON_REPEATABLE_FACTOR, noise_floor
from stiffnet.measurement.statistics import SignalStatistics

#: The shipped settings (under ``configs/``).
SIMULATED_BETA_CONFIG = "simulated_beta.yaml"
#: Manifest columns a row needs besides beta to be simulated at its own operating point.
OPERATING_POINT_COLUMNS = ("gap", "amplitude", "frequency_ratio", "damping_ratio")


class SimulatedBetaConfig(BaseModel):
    """Settings of the reading by simulation (see the module notes).

    Attributes
    ----------
    enabled : bool
        Run it in ``evaluate`` and ``loop``.
    reading : bool
        The loop's reading of a recording is the simulation's where it reproduces the
        recording, the learned model's otherwise.
    beta_range : (float, float)
        Betas of the coarse grid, lowest and highest.
    coarse_points : int
        Log-spaced betas of the coarse grid.
    refine_per_side : int
        Betas added on each side of a row's coarse minimum (0: no refinement).
    interval_rise : float
        The interval's rise above the least discrepancy, in floors (or in ``D_min``).
    reproduce_factor : float
        A recording is reproduced when its least discrepancy is within this many floors.
    periods : float or None
        Natural periods simulated per row (None: the recording's length).
    substeps, min_transient_periods : int, float or None
        The solver's (None: the simulator config's).
    inclination : bool
        Include the inclination statistics in the discrepancy.
    seed : int
        Common-random-number seed of the simulations (initial states, noise).
    """

    model_config = ConfigDict(extra="forbid")

    enabled: bool = True
    reading: bool = True
    beta_range: tuple[float, float] = (4.0, 125.0)
    coarse_points: int = Field(9, ge=3, le=200)
    refine_per_side: int = Field(1, ge=0, le=20)
    interval_rise: float = Field(1.0, gt=0.0)
    reproduce_factor: float = Field(5.0, gt=1.0)
    periods: float | None = Field(None, gt=0.0)
    substeps: int | None = Field(None, ge=1, le=64)
    min_transient_periods: float | None = Field(None, ge=0.0)
    inclination: bool = False
    seed: int = DEFAULT_SEED

    @model_validator(mode="after")
    def _check_range(self) -> SimulatedBetaConfig:
        low, high = self.beta_range
        if not 0.0 < low < high:
            raise ValueError(f"beta_range must be 0 < low < high, got [{low:g}, {high:g}]")
        return self


@lru_cache(maxsize=1)
def simulated_beta_config() -> SimulatedBetaConfig:
    """The shipped settings: ``configs/simulated_beta.yaml``, else the defaults above."""
    from stiffnet.shipped import default_config

    path = default_config(SIMULATED_BETA_CONFIG)
    return load_simulated_beta_config(path) if path.is_file() else SimulatedBetaConfig()


def load_simulated_beta_config(path: str | Path) -> SimulatedBetaConfig:
    """A :class:`SimulatedBetaConfig` from YAML (one-line ``ConfigError`` when invalid)."""
    from stiffnet.config import load_yaml, validate_config

    return validate_config(SimulatedBetaConfig, load_yaml(path), str(path))


def has_operating_point(row: ManifestRow) -> bool:
    """Whether the manifest gives the row's whole operating point (beta aside)."""
    return all(getattr(row, c) is not None for c in OPERATING_POINT_COLUMNS)


def coarse_grid(config: SimulatedBetaConfig) -> np.ndarray:
    """The coarse grid's betas (log-spaced over the range)."""
    low, high = config.beta_range
    return np.exp(np.linspace(np.log(low), np.log(high), config.coarse_points))


def refined_betas(grid: np.ndarray, k: int, per_side: int) -> np.ndarray:
    """Betas between the coarse minimum ``grid[k]`` and each neighbour, evenly in log."""
    lg = np.log(grid)
    out = []
    for j in (k - 1, k + 1):
        if 0 <= j < grid.size:
            t = np.arange(1, per_side + 1) / (per_side + 1)
            out.extend(np.exp(lg[k] + t * (lg[j] - lg[k])))
    return np.sort(np.asarray(out, dtype=np.float64))


def profile_discrepancies(
    measured: Sequence[SignalStatistics],
    rows: Sequence[ManifestRow],
    lengths: Sequence[int],
    betas: Sequence[np.ndarray],
    effects: Sequence[Effect],
    settings: CampaignSolverSettings,
    seed: int,
    inclination: bool,
) -> list[np.ndarray]:
    """``D(beta)`` of each row at its own betas, every row and beta in one simulated batch
    (NaN where a simulation cannot be analysed)."""
    from stiffnet.campaign.simulate import natural_frequency
    from stiffnet.errors import SignalError
    from stiffnet.measurement.statistics import signal_statistics

    alt = [r.model_copy(update={"beta": float(b)}) for r, bs in zip(rows, betas, strict=True)
           for b in bs]  # fmt: skip
    n_per = [len(bs) for bs in betas]
    sims = simulate_rows(alt, effects, [n for n, m in zip(lengths, n_per, strict=True)
                                        for _ in range(m)], seed, settings)  # fmt: skip
    out, at = [], 0
    for m, per in zip(measured, n_per, strict=True):
        d = np.full(per, np.nan)
        for j in range(per):
            row, a = alt[at + j], sims[at + j]
            try:
                s = signal_statistics(a, row.fs_hz, natural_frequency(row), row.frequency_ratio,
                                      inclination)  # fmt: skip
            except SignalError:
                continue
            d[j] = recording_discrepancy(normalised_differences(m, s))
        out.append(d)
        at += per
    return out


def local_parabola(betas: np.ndarray, d: np.ndarray) -> tuple[float, float, float, int]:
    """(log beta, D, curvature, index) of the least discrepancy of a sorted profile: the
    vertex of the parabola in log beta through the least point and its two neighbours (kept
    between them); curvature 0 where there is no such parabola (an edge, a missing
    neighbour, a profile not convex there): the least point itself."""
    ok = np.isfinite(d)
    k = int(np.argmin(np.where(ok, d, np.inf)))
    if 0 < k < betas.size - 1 and ok[k - 1 : k + 2].all():
        x, y = np.log(betas[k - 1 : k + 2]), d[k - 1 : k + 2]
        a, b, c = np.polyfit(x - x[1], y, 2)
        if a > 0:
            v = float(np.clip(-b / (2 * a), x[0] - x[1], x[2] - x[1]))
            return float(x[1] + v), float(min(a * v * v + b * v + c, y[1])), float(a), k
    return float(np.log(betas[k])), float(d[k]), 0.0, k


def least_discrepancy(betas: np.ndarray, d: np.ndarray) -> float:
    """The profile's least discrepancy: the local parabola's at its vertex (not below 0),
    so that a minimum between two grid points is not taken for a misfit."""
    return max(local_parabola(betas, d)[1], 0.0)


def profile_interval(
    betas: np.ndarray, d: np.ndarray, k: int, threshold: float
) -> tuple[float, float, bool]:
    """(low, high, open): the connected betas around index ``k`` where ``D <= threshold``,
    interpolated in log beta; ``open`` when it reaches the grid's edge."""
    lg = np.log(betas)
    inside = np.isfinite(d) & (d <= threshold)
    lo = hi = k
    while lo > 0 and inside[lo - 1]:
        lo -= 1
    while hi < betas.size - 1 and inside[hi + 1]:
        hi += 1
    edge = lo == 0 or hi == betas.size - 1

    def cross(i_in: int, i_out: int) -> float:
        if not np.isfinite(d[i_out]):
            return float(betas[i_out])
        t = (threshold - d[i_in]) / (d[i_out] - d[i_in])
        return float(np.exp(lg[i_in] + np.clip(t, 0.0, 1.0) * (lg[i_out] - lg[i_in])))

    low = float(betas[0]) if lo == 0 else cross(lo, lo - 1)
    high = float(betas[-1]) if hi == betas.size - 1 else cross(hi, hi + 1)
    return low, high, edge


def beta_interval(
    betas: np.ndarray, d: np.ndarray, rise: float
) -> tuple[float, float, float, bool]:
    """(beta, low, high, open) of a sorted profile ``D(beta)`` whose tolerance above its
    least value is ``rise`` (module notes).

    Near the minimum the interval is the local parabola's (``x0 +- sqrt(rise / a)`` in log
    beta: the profile is sampled too coarsely there for interpolation, which cuts a convex
    profile short); farther out, the profile's own crossing by interpolation between its
    points; the wider of the two on each side, never past the grid.
    """
    x0, d0, a, k = local_parabola(betas, d)
    threshold = max(d0, 0.0) + rise
    low, high, edge = profile_interval(betas, d, k, threshold)
    if a > 0:
        h = np.sqrt(max(threshold - d0, 0.0) / a)
        low = min(low, float(np.exp(x0 - h)))
        high = max(high, float(np.exp(x0 + h)))
    low, high = max(low, float(betas[0])), min(high, float(betas[-1]))
    edge = edge or low <= betas[0] or high >= betas[-1]
    return float(np.exp(x0)), low, high, bool(edge)


def solver_settings(
    config: SimulatedBetaConfig, base: CampaignSolverSettings | None = None
) -> CampaignSolverSettings:
    """The simulations' settings: the simulator config's, with this reading's overrides."""
    update: dict[str, Any] = {"periods": config.periods}
    if config.substeps is not None:
        update["substeps"] = config.substeps
    if config.min_transient_periods is not None:
        update["min_transient_periods"] = config.min_transient_periods
    return (base or CampaignSolverSettings()).model_copy(update=update)


def two_batch_profiles(
    measured: Sequence[SignalStatistics],
    rows: Sequence[ManifestRow],
    lengths: Sequence[int],
    effects: Sequence[Effect],
    settings: CampaignSolverSettings,
    cfg: SimulatedBetaConfig,
) -> tuple[list[tuple[np.ndarray, np.ndarray]], dict[str, float]]:
    """Each row's profile ``(betas, D)``, sorted by beta: the coarse grid in one batch, then
    the betas around each row's coarse minimum in another; and each batch's CPU seconds."""
    grid = coarse_grid(cfg)
    args = (measured, rows, lengths)
    c0 = time.process_time()
    coarse = profile_discrepancies(*args, [grid] * len(rows), effects, settings, cfg.seed,
                                   cfg.inclination)  # fmt: skip
    c1 = time.process_time()
    extra = [refined_betas(grid, int(np.argmin(np.where(np.isfinite(d), d, np.inf))),
                           cfg.refine_per_side) for d in coarse]  # fmt: skip
    fine = (profile_discrepancies(*args, extra, effects, settings, cfg.seed, cfg.inclination)
            if cfg.refine_per_side else [np.empty(0)] * len(rows))  # fmt: skip
    cpu = {"coarse": round(c1 - c0, 2), "refine": round(time.process_time() - c1, 2)}
    out = []
    for dc, e, dfine in zip(coarse, extra, fine, strict=True):
        b = np.concatenate([grid, e])
        order = np.argsort(b)
        out.append((b[order], np.concatenate([dc, dfine])[order]))
    return out, cpu


def beta_by_least_discrepancy(
    campaign: Campaign,
    effects: Sequence[Effect],
    config: SimulatedBetaConfig | None = None,
    base_settings: CampaignSolverSettings | None = None,
) -> dict[str, Any]:
    """Each recording's beta at the least discrepancy against ``effects`` (module notes).

    Parameters
    ----------
    campaign : Campaign
    effects : sequence of Effect
        The physics to read beta with (the loop's current law and nuisances at their fit).
    config : SimulatedBetaConfig, optional
        Default: the shipped ``configs/simulated_beta.yaml``.
    base_settings : CampaignSolverSettings, optional
        The simulator config's solver settings (default: the campaign default).

    Returns
    -------
    dict
        ``recordings`` (per manifest row: ``recording``, ``class``, ``beta``,
        ``beta_interval``, ``interval_open``, ``least_discrepancy``, ``floor``,
        ``reproduction_floor``, ``floor_ratio``, ``reproduced``, ``profile`` ([beta, D]
        pairs), ``reason``;
        ``class`` and ``beta`` are None where the row has no operating point),
        ``settings``, ``rule`` (the interval and reproduction rules in words),
        ``simulated`` (trajectories) and ``cpu_seconds``.
    """
    from stiffnet.measurement.target import measured_statistics

    cfg = config or simulated_beta_config()
    c0 = time.process_time()
    settings = solver_settings(cfg, base_settings)
    idx = [i for i, r in enumerate(campaign.rows) if has_operating_point(r)]
    rows = [campaign.rows[i] for i in idx]
    result = [_unread(r) for r in campaign.rows]
    n_sim, cpu = 0, {}
    if rows:
        meas, lengths, samples = measured_statistics(campaign, rows, cfg.inclination)
        floors = noise_floor(samples, rows, settings.periods, cfg.inclination)["floors"]
        f = floors.effective()
        # a non-repeatable recording's own floor is one draw of a wandering orbit: a match
        # within it does not pin beta, so reproduction is judged at most against the
        # non-repeatable limit (the interval keeps the recording's own floor)
        f_rep = np.minimum(f, NON_REPEATABLE_FACTOR * floors.median)
        # rows without impacts have nothing for beta to act on: not simulated
        live = [j for j, m in enumerate(meas) if m.has_impacts]
        for j, row in enumerate(rows):
            result[idx[j]] = _no_impacts(row, float(f[j]))
        profiles, cpu = two_batch_profiles(
            [meas[j] for j in live], [rows[j] for j in live], [lengths[j] for j in live],
            effects, settings, cfg,
        )  # fmt: skip
        n_sim = sum(b.size for b, _ in profiles)
        for j, (b, d) in zip(live, profiles, strict=True):
            result[idx[j]] = _read(rows[j], b, d, float(f[j]), float(f_rep[j]), cfg)
    return {
        "recordings": result,
        "settings": cfg.model_dump(mode="json"),
        "rule": (
            f"beta at the least discrepancy; interval where D <= D_min + {cfg.interval_rise:g} "
            f"max(floor, D_min); reproduced when D_min <= {cfg.reproduce_factor:g} floors"
        ),
        "simulated": int(n_sim),
        "cpu_seconds": {**cpu, "total": round(time.process_time() - c0, 2)},
    }


def _read(
    row: ManifestRow,
    betas: np.ndarray,
    d: np.ndarray,
    floor: float,
    reproduction_floor: float,
    cfg: SimulatedBetaConfig,
) -> dict[str, Any]:
    """One recording's reading from its profile (``floor``: its own, for the interval;
    ``reproduction_floor``: the floor its least discrepancy is judged against)."""
    if not np.isfinite(d).any():
        return {**_unread(row), "floor": floor, "reason": "no simulation could be analysed"}
    d_min = least_discrepancy(betas, d)
    beta, low, high, edge = beta_interval(betas, d, cfg.interval_rise * max(floor, d_min))
    ratio = d_min / reproduction_floor
    reproduced = bool(ratio <= cfg.reproduce_factor)
    reason = (
        f"least discrepancy {d_min:.3g} at beta {beta:.3g}, {ratio:.2g}x the recording's floor"
        + ("" if reproduction_floor >= floor else " (the non-repeatable limit: its own is higher)")
        + ("" if reproduced else f": no beta reproduces it (over {cfg.reproduce_factor:g}x)")
        + ("; the interval reaches the grid's edge" if edge else "")
    )
    return {
        "recording": row.recording,
        "class": str(beta_class(beta)),
        "beta": beta,
        "beta_interval": [low, high],
        "interval_open": edge,
        "least_discrepancy": d_min,
        "floor": floor,
        "reproduction_floor": reproduction_floor,
        "floor_ratio": ratio,
        "reproduced": reproduced,
        "profile": [
            [round(float(b), 4), None if not np.isfinite(v) else round(float(v), 5)]
            for b, v in zip(betas, d, strict=True)
        ],  # fmt: skip
        "reason": reason,
    }


def _no_impacts(row: ManifestRow, floor: float) -> dict[str, Any]:
    """A recording without impacts: no_contact, nothing for beta to act on."""
    return {**_unread(row), "class": NO_CONTACT, "floor": floor,
            "reason": "no impacts in the recording: beta does not act on it"}  # fmt: skip


def _unread(row: ManifestRow) -> dict[str, Any]:
    """A row the simulation does not read (no operating point in the manifest)."""
    return {
        "recording": row.recording,
        "class": None,
        "beta": None,
        "beta_interval": None,
        "interval_open": None,
        "least_discrepancy": None,
        "floor": None,
        "reproduction_floor": None,
        "floor_ratio": None,
        "reproduced": None,
        "profile": [],
        "reason": "the manifest lacks the operating point ("
        + ", ".join(c for c in OPERATING_POINT_COLUMNS if getattr(row, c) is None)
        + ")",
    }
