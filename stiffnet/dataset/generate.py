"""Simulate labelled acceleration windows, shard by shard."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from stiffnet import __version__
from stiffnet.config.sim import SimulationConfig
from stiffnet.dataset.labels import window_labels
from stiffnet.dataset.sampling import TrajectoryPlan, sample_plan
from stiffnet.dataset.store import write_card, write_shard
from stiffnet.io_utils import atomic_directory
from stiffnet.simulator.simulator import Simulator


def shard_rng(seed: int, shard: int) -> np.random.Generator:
    """The generator of one shard: a function of (seed, shard) only, so a dataset is
    identical however its shards are scheduled."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(shard,)))


def shard_sizes(cfg: SimulationConfig) -> list[int]:
    n, k = cfg.n_trajectories, cfg.shard_size
    return [min(k, n - i) for i in range(0, n, k)]


def build_simulator(cfg: SimulationConfig) -> Simulator:
    s = cfg.solver
    return Simulator(
        [e.build() for e in cfg.effects],
        settle_tolerance=s.settle_tolerance,
        min_transient_periods=s.min_transient_periods,
        substeps=s.substeps,
    )


def simulate_shard(cfg: SimulationConfig, shard: int, n: int) -> pa.Table:
    """Simulate the ``n`` trajectories of shard ``shard`` and cut them into windows."""
    rng = shard_rng(cfg.seed, shard)
    plan = sample_plan(cfg, n, rng)
    sim = build_simulator(cfg)
    # Rows with similar window lengths share a batch, so little is simulated in vain.
    order = np.argsort(plan.window_samples, kind="stable")
    parts = []
    for start in range(0, n, cfg.solver.batch_size):
        rows = order[start : start + cfg.solver.batch_size]
        parts.append(_simulate_rows(cfg, sim, plan.subset(rows), rows, shard, rng))
    table = pa.concat_tables(parts)
    return table.sort_by([("trajectory", "ascending"), ("window", "ascending")])


def _simulate_rows(cfg, sim, plan: TrajectoryPlan, rows, shard, rng) -> pa.Table:
    per = cfg.windows.per_trajectory
    n_samples = int(per * plan.window_samples.max())
    res = sim.simulate(plan.batch, plan.fs_ratio, n_samples, noise=plan.noise, rng=rng)
    edges = [c.beta[0] for c in cfg.classes] + [cfg.classes[-1].beta[1]]
    cols: dict[str, list[Any]] = {k: [] for k in _COLUMNS}
    effect_cols: dict[str, list[float]] = {}
    b = plan.batch
    for i in range(len(plan)):
        w = int(plan.window_samples[i])
        for j in range(per):
            sl = slice(j * w, (j + 1) * w)
            impacts = int(res.impacts[i, sl].sum())
            contact = float(np.mean(res.contact_force[i, sl] > 0))
            cols["accel"].append(res.accel[i, sl].astype(np.float32))
            cols["trajectory"].append(shard * cfg.shard_size + int(rows[i]))
            cols["window"].append(j)
            cols["shard"].append(shard)
            cols["n_impacts"].append(impacts)
            cols["contact_fraction"].append(contact)
            for name in ("beta", "gap", "amplitude", "omega", "damping", "natural_frequency_hz"):
                cols[name].append(float(getattr(b, name)[i]))
            cols["fs_ratio"].append(float(plan.fs_ratio[i]))
            cols["fs_hz"].append(float(plan.fs_ratio[i] * b.natural_frequency_hz[i]))
            cols["noise"].append(float(plan.noise[i]))
            for eff, params in res.effect_params.items():
                for p, values in params.items():
                    effect_cols.setdefault(f"effect.{eff}.{p}", []).append(float(values[i]))
    has_contact = (np.array(cols["n_impacts"]) > 0) | (np.array(cols["contact_fraction"]) > 0)
    labels = window_labels(np.array(cols["beta"]), has_contact, edges)
    names = cfg.class_names()
    cols["label"] = labels.tolist()
    cols["class"] = [names[k] for k in labels]
    arrays = {k: pa.array(v, type=pa.list_(pa.float32())) if k == "accel" else pa.array(v)
              for k, v in cols.items()}  # fmt: skip
    arrays.update({k: pa.array(v, type=pa.float64()) for k, v in effect_cols.items()})
    return pa.table(arrays)


_COLUMNS = (
    "accel", "trajectory", "window", "shard", "n_impacts", "contact_fraction", "beta", "gap",
    "amplitude", "omega", "damping", "natural_frequency_hz", "fs_ratio", "fs_hz", "noise",
)  # fmt: skip


def generate_dataset(
    cfg: SimulationConfig,
    out: str | Path,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Simulate the whole dataset into ``out`` (atomically) and return its data card."""
    sizes = shard_sizes(cfg)
    t_start = time.perf_counter()
    shards = []
    counts: dict[str, int] = dict.fromkeys(cfg.class_names(), 0)
    n_windows = 0
    with atomic_directory(out, overwrite=overwrite) as tmp:
        for shard, n in enumerate(sizes):
            table = simulate_shard(cfg, shard, n)
            shards.append(write_shard(tmp, shard, table))
            for name, k in zip(*np.unique(table["class"].to_numpy(zero_copy_only=False),
                                          return_counts=True), strict=True):  # fmt: skip
                counts[str(name)] += int(k)
            n_windows += table.num_rows
            if progress:
                progress(shard + 1, len(sizes))
        card = {
            "kind": "stiffnet-dataset",
            "format": "parquet shards, one row per window, accel as list<float32>",
            "stiffnet_version": __version__,
            "code_version": _code_version(),
            "seed": cfg.seed,
            "n_trajectories": cfg.n_trajectories,
            "n_windows": n_windows,
            "class_names": cfg.class_names(),
            "class_balance": counts,
            "engine": build_simulator(cfg).engine,
            # the numpy and compiled closed-form engines agree to ~1e-8 but part on
            # chaotic orbits: a dataset is reproduced exactly by the same one
            "compiled": _compiled_used(cfg),
            "seconds": round(time.perf_counter() - t_start, 3),
            "shards": shards,
            "config": cfg.model_dump(mode="json"),
        }
        write_card(tmp, card)
    return card


def _compiled_used(cfg: SimulationConfig) -> bool:
    from stiffnet.simulator import compiled

    sim = build_simulator(cfg)
    return bool(sim.engine == "closed_form" and sim.compiled and compiled.available())


def _code_version() -> str:
    """Git commit of the stiffnet checkout, when there is one."""
    import subprocess

    try:
        here = Path(__file__).resolve().parent
        out = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "--short", "HEAD"],
            capture_output=True, text=True, timeout=5, check=True,
        )  # fmt: skip
        dirty = subprocess.run(
            ["git", "-C", str(here), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=5, check=True,
        ).stdout.strip()  # fmt: skip
        return out.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
