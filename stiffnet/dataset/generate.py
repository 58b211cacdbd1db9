"""Simulate labelled acceleration windows, shard by shard."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from stiffnet import __version__
from stiffnet.config.sim import SimulationConfig
from stiffnet.dataset.labels import window_labels
from stiffnet.dataset.sampling import TrajectoryPlan, sample_plan
from stiffnet.dataset.store import (
    CARD,
    JOB,
    RECORDS,
    SHARDS,
    finished_shard,
    shard_name,
    write_card,
    write_shard,
    write_shard_record,
)
from stiffnet.errors import StiffnetError
from stiffnet.io_utils import (
    check_replaceable_folder,
    new_marker,
    output_lock,
    write_json_atomic,
)
from stiffnet.simulator.simulator import RowDraws, Simulator


def shard_rng(seed: int, shard: int) -> np.random.Generator:
    """The generator of one shard: a function of (seed, shard) only, so a dataset is
    identical however its shards are scheduled."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(shard,)))


def shard_sizes(cfg: SimulationConfig) -> list[int]:
    n, k = cfg.n_trajectories, cfg.shard_size
    return [min(k, n - i) for i in range(0, n, k)]


def build_simulator(cfg: SimulationConfig, without: frozenset[str] = frozenset()) -> Simulator:
    """The simulator of ``cfg``'s effects, less those named in ``without``."""
    effects = [e.build() for e in cfg.effects]
    return Simulator([e for e in effects if e.name not in without], cfg.solver)


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
        ids = shard * cfg.shard_size + rows
        parts.append(_simulate_rows(cfg, sim, plan.subset(rows), ids, np.full(rows.size, shard),
                                    rng))  # fmt: skip
    table = pa.concat_tables(parts)
    return table.sort_by([("trajectory", "ascending"), ("window", "ascending")])


#: What the configs of :func:`simulate_shards` must share (one simulator, one labelling).
SHARED_FIELDS = ("seed", "shard_size", "classes", "windows", "effects", "ideal_fraction",
                 "solver")  # fmt: skip


def simulate_shards(cfgs: list[SimulationConfig], shards: list[int]) -> list[pa.Table]:
    """Simulate several shards whose configs differ only in their sweep, in shared batches.

    The numerical engine's cost is mostly its steps, each a few dozen numpy operations
    over the batch's rows, and a batch takes as many steps as its slowest row needs:
    a batch of 16 trajectories costs well over half of one of 64 (docs/measurement_loop.md,
    "The loop on the two-stage campaign"). Shards of a few trajectories each (one per
    operating point of a campaign) therefore run together. Every random draw is the one
    :func:`simulate_shard` makes: each shard's plan, initial states, effect parameters,
    measurement chain and noise come from its own generator (:func:`shard_rng`) in its own
    batches (:func:`_shard_pieces`); only the motion, which draws nothing, is computed in
    batches of ``solver.batch_size`` rows of all shards (similar window lengths together).
    A shard is thus a function of the seed and its own index, as alone. With the numerical
    engine its windows still differ from the shard simulated alone (the transient's step
    count and the record's substep are a batch's): mostly by the integrator's error, but a
    row near a change of orbit may reach another motion (5.1 % of the windows beyond the
    noise at the rig's 24 points; docs/measurement_loop.md, "Shared batches: the per-shard
    draws").

    Returns
    -------
    list of pyarrow.Table
        One table per shard, in ``shards``' order, sorted by trajectory and window.

    Raises
    ------
    StiffnetError
        The configs differ in more than their sweep and counts (:data:`SHARED_FIELDS`), or
        a measurement effect drew by the signal's values (the draws then are not a shard's).
    """
    if len(cfgs) != len(shards) or not cfgs:
        raise StiffnetError("simulate_shards needs one shard index per config, at least one")
    first = cfgs[0]
    for c in cfgs[1:]:
        differ = [f for f in SHARED_FIELDS if getattr(c, f) != getattr(first, f)]
        if differ:
            raise StiffnetError(f"shards simulated together must share {', '.join(differ)}")
    sim = build_simulator(first)
    sims: dict[frozenset[str], Simulator] = {frozenset(): sim}
    pieces = [p for c, s in zip(cfgs, shards, strict=True) for p in _shard_pieces(c, s, sim, sims)]
    # every row of every piece: (piece, row in the piece), shared batches by window length
    owner = np.concatenate([np.full(len(p.plan), k) for k, p in enumerate(pieces)])
    local = np.concatenate([np.arange(len(p.plan)) for p in pieces])
    width = np.concatenate([p.plan.window_samples for p in pieces])
    left = [len(p.plan) for p in pieces]
    motions: list[dict[str, np.ndarray]] = [{} for _ in pieces]
    tables: dict[int, list[pa.Table]] = {s: [] for s in shards}
    order = np.argsort(width, kind="stable")
    for start in range(0, len(order), first.solver.batch_size):
        chunk = order[start : start + first.solver.batch_size]
        for off in dict.fromkeys(pieces[k].off for k in owner[chunk]):
            rows = chunk[[pieces[k].off == off for k in owner[chunk]]]
            _shared_motion(first, pieces, owner[rows], local[rows], motions)
            for k in set(owner[rows].tolist()):
                left[k] -= int(np.sum(owner[rows] == k))
                if not left[k]:  # measured and windowed as soon as its rows are all moved
                    tables[pieces[k].shard].append(_measured_piece(sim, pieces[k], motions[k]))
                    motions[k] = {}
    by = [("trajectory", "ascending"), ("window", "ascending")]
    return [pa.concat_tables(tables[s]).sort_by(by) for s in shards]


@dataclass
class _Piece:
    """One :meth:`Simulator.simulate` call of :func:`simulate_shard` (a group of rows of one
    of a shard's batches): its rows, the draws made before its motion and where its
    generator stood before and after its measurement chain."""

    shard: int
    cfg: SimulationConfig
    plan: TrajectoryPlan
    trajectory: np.ndarray
    off: frozenset[str]
    sim: Simulator
    n_samples: int
    draws: RowDraws
    rng: np.random.Generator
    before_measure: dict[str, Any]
    after_measure: dict[str, Any]


def _shard_pieces(
    cfg: SimulationConfig, shard: int, sim: Simulator, sims: dict[frozenset[str], Simulator]
) -> list[_Piece]:
    """Every draw :func:`simulate_shard` makes for ``shard``, in its order, without the motion.

    The measurement chain draws after the motion and by the signal's shape only, so it is
    run on zeros to move the generator past it; :func:`_measured_piece` runs it again on
    the motion from where it started and checks that it ends where this one did.
    """
    rng = shard_rng(cfg.seed, shard)
    plan = sample_plan(cfg, cfg.n_trajectories, rng)
    order = np.argsort(plan.window_samples, kind="stable")
    per = cfg.windows.per_trajectory
    pieces = []
    for start in range(0, len(plan), cfg.solver.batch_size):
        rows = order[start : start + cfg.solver.batch_size]
        n_samples = int(per * plan.window_samples[rows].max())
        for sub_rows, off in _groups(sim, plan.subset(rows)):
            if off not in sims:
                sims[off] = build_simulator(cfg, off)
            gsim = sims[off]
            idx = rows[sub_rows]
            sub = plan.subset(idx)
            draws = gsim.draw_inputs(sub.batch, rng, effect_params=_kept(sub.effect_params, off),
                                     active=_kept(sub.active, off))  # fmt: skip
            before = rng.bit_generator.state
            width = (n_samples + int(lead_samples(gsim, sub).max(initial=0))) * (
                gsim.settings.oversampled
            )
            measured(gsim, np.zeros((len(sub), width)), sub, draws, rng)
            after = rng.bit_generator.state
            trajectory = shard * cfg.shard_size + idx
            pieces.append(_Piece(shard, cfg, sub, trajectory, off, gsim, n_samples, draws, rng,
                                 before, after))  # fmt: skip
    return pieces


def _shared_motion(cfg, pieces: list[_Piece], owner, local, motions) -> None:
    """The motion of rows of several pieces of one group (``owner``, row ``local`` in it) as
    one batch, each row kept in ``motions[owner]`` for its piece's ``n_samples``."""
    pairs = list(zip(owner, local, strict=True))
    plan = TrajectoryPlan.concatenate([pieces[k].plan.subset(np.array([i])) for k, i in pairs])

    def gather(get: Callable[[RowDraws], Any]) -> np.ndarray:
        return np.array([_row(get(pieces[k].draws), i) for k, i in pairs])

    params = {
        name: {key: gather(lambda d, n=name, q=key: d.params[n][q]) for key in values}
        for name, values in pieces[owner[0]].draws.params.items()
    }
    draws = RowDraws(gather(lambda d: d.x0), gather(lambda d: d.v0), params, {})
    n_samples = max(pieces[k].n_samples for k in owner)
    row_samples = cfg.windows.per_trajectory * plan.window_samples
    sim = pieces[owner[0]].sim
    res = logger_motion(sim, plan, n_samples, draws, row_samples)
    for j, (k, i) in enumerate(zip(owner, local, strict=True)):
        m, n = motions[k], pieces[k].n_samples
        # the chain's input keeps its finer rate and the piece's longest lead-in (measured's
        # width; a batch of shorter lead-ins leaves zeros past this row's record)
        lead = int(lead_samples(sim, pieces[k].plan).max(initial=0))
        width = {"accel": (n + lead) * sim.settings.oversampled}
        for key, rows in res.items():
            row = rows[j, : width.get(key, n)]
            shape = (len(pieces[k].plan), width.get(key, n))
            m.setdefault(key, np.zeros(shape, rows.dtype))[i, : row.size] = row


def _row(value: np.ndarray, i: int) -> float:
    """Row ``i`` of a per-row parameter (a scalar is every row's)."""
    v = np.asarray(value)
    return v.item() if v.ndim == 0 else v[i]


def _measured_piece(sim: Simulator, piece: _Piece, motion: dict) -> pa.Table:
    """The piece's motion through its measurement chain, drawn from where its shard's
    generator stood, cut into windows."""
    gsim, rng = piece.sim, piece.rng
    rng.bit_generator.state = piece.before_measure
    sub = piece.plan
    accel = measured(gsim, motion["accel"], sub, piece.draws, rng)
    if rng.bit_generator.state != piece.after_measure:
        raise StiffnetError("a measurement effect drew by the signal's values: shards in "
                            "shared batches would not keep their own draws")  # fmt: skip
    res = {"accel": accel, "contact_force": motion["contact_force"],
           "impacts": motion["impacts"]}  # fmt: skip
    return _window_table(piece.cfg, sim, sub, res, piece.trajectory,
                         np.full(len(sub), piece.shard))  # fmt: skip


def _switchable(sim: Simulator) -> set[str]:
    """Effects that can be off row by row inside one batch (see ``Simulator.simulate``)."""
    return {e.name for e in sim.effects if e.kind == "measurement" or e.neutral is not None}


def _groups(sim: Simulator, plan: TrajectoryPlan) -> list[tuple[np.ndarray, frozenset[str]]]:
    """The plan's rows by the effects they lack that cannot be off inside a batch (a
    non-piecewise-linear contact law, say): each group's rows and those effects."""
    fixed = [name for name in plan.active if name not in _switchable(sim)]
    key = np.array([[plan.active[name][i] for name in fixed] for i in range(len(plan))], bool)
    key = key.reshape(len(plan), len(fixed))
    out = []
    for g in np.unique(key, axis=0):
        rows = np.flatnonzero((key == g).all(axis=1))
        out.append((rows, frozenset(name for name, on in zip(fixed, g, strict=True) if not on)))
    return out


def _kept(values: dict[str, Any], off: frozenset[str]) -> dict[str, Any]:
    return {k: v for k, v in values.items() if k not in off}


def _simulate_plan(cfg, sim, plan: TrajectoryPlan, n_samples: int, rng):
    """Simulate a plan whose rigs differ in which effects they have.

    Rows lacking an effect that cannot be switched off inside a batch (a
    non-piecewise-linear contact law, say) run on a simulator without it, so
    the rest keep the fast closed-form engine. Returns accel, impacts and
    contact force ``(B, N)``.
    """
    out = {k: np.zeros((len(plan), n_samples)) for k in ("accel", "contact_force")}
    out["impacts"] = np.zeros((len(plan), n_samples), dtype=bool)
    for rows, off in _groups(sim, plan):
        gsim = sim if not off else build_simulator(cfg, off)
        sub = plan.subset(rows)
        row_samples = cfg.windows.per_trajectory * sub.window_samples
        if gsim.settings.oversampled == 1:
            res = gsim.simulate(
                sub.batch, sub.fs_ratio, n_samples, noise=sub.noise, rng=rng,
                effect_params=_kept(sub.effect_params, off), active=_kept(sub.active, off),
                row_samples=row_samples,
            )  # fmt: skip
            for k in out:
                out[k][rows] = getattr(res, k)
            continue
        draws = gsim.draw_inputs(sub.batch, rng, effect_params=_kept(sub.effect_params, off),
                                 active=_kept(sub.active, off))  # fmt: skip
        motion = logger_motion(gsim, sub, n_samples, draws, row_samples)
        motion["accel"] = measured(gsim, motion["accel"], sub, draws, rng)
        for k in out:
            out[k][rows] = motion[k]
    return out


def lead_samples(sim: Simulator, plan: TrajectoryPlan) -> np.ndarray:
    """Logger's samples simulated and dropped before each row's record (B,): in an
    oversampled world, the lead-in of the campaign's comparisons
    (:func:`stiffnet.campaign.simulate.lead_in_seconds`), so the analog chain's start-up
    transient is not in the windows; none at the logger's rate.

    The chain's filters start in the steady state for a constant input equal to the first
    sample: a charge amplifier's high-pass then takes that sample for a DC level and subtracts
    it, decaying over ``1 / w_h`` (0.5 s at 0.3 Hz), where the hardware had been running and
    the diagnosis's simulations drop a lead-in. Measured on the independent rig's
    Hunt-Crossley campaign (a 0.23-0.38 Hz high-pass in the world, 3 s lead-in): the loop's
    GBM read the campaign the same with it or without (0.833 / beta MAPE 0.074 and 0.075),
    at 168 CPU s for the dataset instead of 119; without a high-pass the lead-in is 0.1 s."""
    if sim.settings.oversampled == 1:
        return np.zeros(len(plan), dtype=np.int64)
    from stiffnet.campaign.simulate import LONGEST_COMPARISON_LEAD_IN_S, lead_in_seconds

    lead_s = lead_in_seconds(sim.effects, LONGEST_COMPARISON_LEAD_IN_S)
    fs_hz = plan.fs_ratio * plan.batch.natural_frequency_hz
    return np.ceil(lead_s * fs_hz).astype(np.int64)


def logger_motion(
    sim: Simulator, plan: TrajectoryPlan, n_samples: int, draws: RowDraws, row_samples: np.ndarray
) -> dict[str, np.ndarray]:
    """The motion of ``plan``'s rows for ``n_samples`` logger's samples: ``contact_force`` and
    ``impacts`` at the logger's rate, ``accel`` at ``sim.settings.oversampled`` (``k``) times
    it, each row's lead-in (:func:`lead_samples`) ahead of its record.

    An analog sensor chain filters the continuous signal and the logger samples its output
    (:data:`stiffnet.campaign.simulate.ANALOG_OVERSAMPLING`): a world whose solver is
    oversampled simulates the motion ``k`` times finer, for :func:`measured` to filter before
    it keeps every ``k``-th sample. An impact falls in a logger's sample where it falls in
    any of its ``k`` fine ones.
    """
    k = sim.settings.oversampled
    lead = lead_samples(sim, plan)
    total = n_samples + int(lead.max(initial=0))
    res = sim.motion_of(plan.batch, plan.fs_ratio * k, total * k, draws, (row_samples + lead) * k)
    record = lead[:, None] * k + np.arange(n_samples * k)[None, :]
    impacts = np.take_along_axis(np.asarray(res.impacts), record, axis=1)
    force = np.take_along_axis(np.asarray(res.contact_force, np.float64), record[:, ::k], axis=1)
    return {"accel": np.asarray(res.accel, np.float64),
            "contact_force": force,
            "impacts": impacts.reshape(len(plan), n_samples, k).any(axis=2)}  # fmt: skip


def measured(
    sim: Simulator,
    accel: np.ndarray,
    plan: TrajectoryPlan,
    draws: RowDraws,
    rng: np.random.Generator,
) -> np.ndarray:
    """``accel`` (:func:`logger_motion`'s) through the measurement chain, each row's record
    sampled at the logger's rate, with the white noise.

    Oversampled, the chain runs at the fine rate over the lead-in and the record, and the
    noise is drawn for the logger's samples only, after the chain (the logger's noise, as
    ``campaign.simulate`` draws it); at the logger's rate it is :meth:`Simulator.measure` as
    it always was.
    """
    k = sim.settings.oversampled
    if k == 1:
        return sim.measure(accel, plan.batch, plan.fs_ratio, plan.noise, draws, rng)
    lead = lead_samples(sim, plan)
    n = accel.shape[1] // k - int(lead.max(initial=0))
    fine = sim.measure(accel, plan.batch, plan.fs_ratio * k, np.zeros(len(plan)), draws, rng)
    out = np.take_along_axis(fine, (lead[:, None] + np.arange(n)[None, :]) * k, axis=1)
    std = plan.noise * plan.batch.forcing_scale
    return out + rng.standard_normal(out.shape) * std[:, None]


def _effect_columns(sim: Simulator, plan: TrajectoryPlan) -> dict[str, np.ndarray]:
    """``effect.<name>.<param>`` (the value the rig had) and ``effect.<name>.active``."""
    cols: dict[str, np.ndarray] = {}
    neutral = {e.name: e.neutral or {} for e in sim.effects if e.kind == "dynamics"}
    for name, params in plan.effect_params.items():
        on = plan.active[name]
        for p, values in params.items():
            off_value = neutral.get(name, {}).get(p)
            v = np.broadcast_to(values, on.shape)
            cols[f"effect.{name}.{p}"] = v if off_value is None else np.where(on, v, off_value)
        cols[f"effect.{name}.active"] = on.astype(np.float64)
    return cols


def _simulate_rows(cfg, sim, plan: TrajectoryPlan, trajectory, shard, rng) -> pa.Table:
    """Simulate ``plan``'s rows as one batch and cut them into labelled windows; each row's
    ``trajectory`` number and ``shard`` are given (B,)."""
    n_samples = int(cfg.windows.per_trajectory * plan.window_samples.max())
    res = _simulate_plan(cfg, sim, plan, n_samples, rng)
    return _window_table(cfg, sim, plan, res, trajectory, shard)


def _window_table(cfg, sim, plan: TrajectoryPlan, res: dict, trajectory, shard) -> pa.Table:
    """``plan``'s simulated rows (``res``: accel, impacts, contact force (B, N)) cut into
    labelled windows."""
    per = cfg.windows.per_trajectory
    per_row_effects = _effect_columns(sim, plan)
    edges = [c.beta[0] for c in cfg.classes] + [cfg.classes[-1].beta[1]]
    cols: dict[str, list[Any]] = {k: [] for k in _COLUMNS}
    effect_cols: dict[str, list[float]] = {}
    b = plan.batch
    for i in range(len(plan)):
        w = int(plan.window_samples[i])
        for j in range(per):
            sl = slice(j * w, (j + 1) * w)
            impacts = int(res["impacts"][i, sl].sum())
            contact = float(np.mean(res["contact_force"][i, sl] > 0))
            cols["accel"].append(res["accel"][i, sl].astype(np.float32))
            cols["trajectory"].append(int(trajectory[i]))
            cols["window"].append(j)
            cols["shard"].append(int(shard[i]))
            cols["n_impacts"].append(impacts)
            cols["contact_fraction"].append(contact)
            for name in ("beta", "gap", "amplitude", "omega", "damping", "natural_frequency_hz"):
                cols[name].append(float(getattr(b, name)[i]))
            cols["fs_ratio"].append(float(plan.fs_ratio[i]))
            cols["fs_hz"].append(float(plan.fs_ratio[i] * b.natural_frequency_hz[i]))
            cols["noise"].append(float(plan.noise[i]))
            for col, values in per_row_effects.items():
                effect_cols.setdefault(col, []).append(float(values[i]))
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


@dataclass(frozen=True)
class ShardJob:
    """One shard task: simulate shard ``shard`` (``n`` trajectories) into ``out``."""

    cfg: SimulationConfig
    out: str
    shard: int
    n: int
    fingerprint: str
    #: testing hook, called with the shard index as the task starts (fault injection)
    before: Callable[[int], None] | None = None


def run_shard_job(job: ShardJob) -> dict[str, Any]:
    """Simulate one shard, write its Parquet file and then its record; return the record.

    A task of its own on Dask: it depends only on ``job``, and what it writes is
    atomic, so running it twice (a retry, a lost worker) is harmless.
    """
    if job.before is not None:
        job.before(job.shard)
    t0 = time.perf_counter()
    table = simulate_shard(job.cfg, job.shard, job.n)
    return write_shard_table(job, table, time.perf_counter() - t0)


def write_shard_table(job: ShardJob, table: pa.Table, seconds: float) -> dict[str, Any]:
    """Write a simulated shard's Parquet file, then its record; return the record."""
    entry = write_shard(Path(job.out), job.shard, table)
    names, counts = np.unique(table["class"].to_numpy(zero_copy_only=False), return_counts=True)
    record = {
        **entry,
        "shard": job.shard,
        "trajectories": job.n,
        "class_counts": {str(k): int(c) for k, c in zip(names, counts, strict=True)},
        "seconds": round(seconds, 3),
        "fingerprint": job.fingerprint,
    }
    write_shard_record(Path(job.out), job.shard, record)
    return record


def config_fingerprint(cfg: SimulationConfig) -> str:
    """What makes two runs the same job: the config and the stiffnet version."""
    text = json.dumps({"config": cfg.model_dump(mode="json"), "version": __version__},
                      sort_keys=True)  # fmt: skip
    return hashlib.sha256(text.encode()).hexdigest()


def generate_dataset(
    cfg: SimulationConfig,
    out: str | Path,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    resume: bool = True,
    retries: int = 2,
    before_shard: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Simulate the dataset into ``out``, shard by shard, and return its data card.

    Each shard is one task (in-process, on a LocalCluster of ``workers`` processes, or
    on the Dask ``scheduler``) writing its own Parquet file atomically; the card is
    written last and declares the dataset complete. The dataset is the same whatever
    runs the shards: a shard depends only on ``(seed, shard index)``.

    Parameters
    ----------
    cfg
        The simulation config.
    out
        The dataset folder. Work happens in place: an interrupted run leaves a folder
        without ``card.json`` (which loaders refuse) that the next run resumes.
    overwrite
        Replace an existing dataset, or an unfinished one of another config (the
        old folder is moved aside before any work, then deleted).
    progress
        ``progress(done, total)`` in shards; shards kept from an earlier run count.
    scheduler, workers
        Where shards run, see :func:`stiffnet.distributed.cluster.dask_client`.
    resume
        Keep the finished shards of an interrupted run of the same config (checked by
        SHA-256 against their records). ``False`` discards an unfinished run (of any
        config) and starts over; a finished dataset still needs ``overwrite``.
    retries
        Extra attempts of a shard task that raised (Dask only).
    before_shard
        Testing hook called in the task with the shard index (fault injection).

    Raises
    ------
    StiffnetError
        ``out`` holds something else (without ``overwrite``), or a shard failed after
        its retries (the message names it; finished shards are kept for a resume).
    """
    from stiffnet.distributed.cluster import check_target

    check_target(scheduler, workers)
    out = Path(out)
    # one writer per folder: a second run (another seed, an --overwrite) is refused, not mixed
    with output_lock(out):
        return _generate_locked(cfg, out, overwrite, progress, scheduler, workers, resume,
                                retries, before_shard)  # fmt: skip


def _generate_locked(
    cfg: SimulationConfig,
    out: Path,
    overwrite: bool,
    progress: Callable[[int, int], None] | None,
    scheduler: str | None,
    workers: int | None,
    resume: bool,
    retries: int,
    before_shard: Callable[[int], None] | None,
) -> dict[str, Any]:
    from stiffnet.distributed.cluster import dask_client
    from stiffnet.distributed.tasks import run_tasks
    from stiffnet.simulator.compiled import limited_threads

    fingerprint = config_fingerprint(cfg)
    keep = _check_folder(out, fingerprint, overwrite=overwrite, resume=resume)
    sizes = shard_sizes(cfg)
    t_start = time.perf_counter()
    # connect (or start the local cluster) before touching the folder: a wrong address
    # leaves nothing behind
    with dask_client(scheduler, workers) as client:
        _prepare_folder(out, fingerprint, keep)
        records: list[dict[str, Any] | None] = [
            finished_shard(out, i, fingerprint) if keep else None for i in range(len(sizes))
        ]
        todo = [i for i, r in enumerate(records) if r is None]
        kept = len(sizes) - len(todo)
        if progress and kept:
            progress(kept, len(sizes))
        # absolute: a worker elsewhere (shared file system) has another working directory
        where = str(out.resolve())
        jobs = [ShardJob(cfg, where, i, sizes[i], fingerprint, before_shard) for i in todo]
        report = run_tasks(
            run_shard_job,
            jobs,
            client=client,
            retries=retries,
            names=[shard_name(i) for i in todo],
            progress=(lambda done, _: progress(kept + done, len(sizes))) if progress else None,
            thread_limit=limited_threads,
        )
    report.raise_failures()
    for i, record in zip(todo, report.results, strict=True):
        records[i] = record
    card = dataset_card(cfg, records, time.perf_counter() - t_start)
    card["run"] = {"backend": report.backend, "shards_kept": kept, "shards_run": len(todo),
                   "rerun": report.rerun}  # fmt: skip
    write_card(out, card)
    return card


def _check_folder(out: Path, fingerprint: str, overwrite: bool, resume: bool) -> bool:
    """Whether ``out`` is an unfinished run of this job to resume; raise if it is refused.

    Only reads: nothing is changed before the cluster is reached.
    """
    if out.exists() and not out.is_dir():
        raise StiffnetError(f"output path exists and is not a folder: {out}")
    if not (out.is_dir() and any(out.iterdir())):
        return False
    job_path = out / JOB
    unfinished = job_path.is_file() and not (out / CARD).exists()
    same = unfinished and _read_fingerprint(job_path) == fingerprint
    if same and resume and not overwrite:
        return True
    if unfinished and resume and not overwrite:
        raise StiffnetError(f"output folder {out} is an unfinished run of another config "
                            "(use --overwrite or --no-resume to restart it)")  # fmt: skip
    if not unfinished and not overwrite:
        raise StiffnetError(f"output folder {out} exists and is not empty (use --overwrite)")
    check_replaceable_folder(out, (JOB,))  # only a dataset folder (its job's run id) is deleted
    return False  # --overwrite, or --no-resume on an unfinished run: start over


def _prepare_folder(out: Path, fingerprint: str, keep: bool) -> None:
    """Resume in ``out`` (``keep``), or start over: an empty folder with its ``job.json``."""
    if keep:
        _remove_stale_temporaries(out)
        return
    if out.is_dir() and any(out.iterdir()):
        _move_aside_and_delete(out)
    out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out / JOB, new_marker("stiffnet-dataset-job", fingerprint=fingerprint))


def _read_fingerprint(path: Path) -> str | None:
    try:
        return json.loads(path.read_text()).get("fingerprint")
    except (OSError, ValueError, AttributeError):
        return None


def _remove_stale_temporaries(out: Path) -> None:
    """Temporary files of tasks killed mid-write (they start with a dot)."""
    for folder in (out / SHARDS, out / RECORDS):
        for tmp in folder.glob(".*.tmp") if folder.is_dir() else ():
            tmp.unlink(missing_ok=True)


def _move_aside_and_delete(out: Path) -> None:
    """Remove ``out`` so that it never looks like a half-deleted finished dataset."""
    trash = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
    os.replace(out, trash / "old")
    shutil.rmtree(trash, ignore_errors=True)


def dataset_card(
    cfg: SimulationConfig, records: list[dict[str, Any] | None], seconds: float
) -> dict[str, Any]:
    """The data card of a dataset simulated from ``cfg``: class counts, priors, timing
    (what a trained model's card cites as its training data)."""
    counts: dict[str, int] = dict.fromkeys(cfg.class_names(), 0)
    for record in records:
        assert record is not None
        for name, k in record["class_counts"].items():
            counts[name] = counts.get(name, 0) + int(k)
    return {
        "kind": "stiffnet-dataset",
        "format": "parquet shards, one row per window, accel as list<float32>",
        "stiffnet_version": __version__,
        "code_version": _code_version(),
        "seed": cfg.seed,
        "n_trajectories": cfg.n_trajectories,
        "n_windows": sum(r["rows"] for r in records if r is not None),
        "class_names": cfg.class_names(),
        "class_balance": counts,
        "engine": _engines(cfg),
        "seconds": round(seconds, 3),
        "shards": [{k: r[k] for k in ("file", "rows", "sha256")} for r in records if r],
        "config": cfg.model_dump(mode="json"),
    }


def _engines(cfg: SimulationConfig) -> str:
    """The engine(s) that ran: rigs without a nonlinear contact keep the closed form."""
    sim = build_simulator(cfg)
    switchable = _switchable(sim)
    partial = cfg.ideal_fraction > 0 or any(
        e.probability < 1 for e in cfg.effects if e.build().name not in switchable
    )
    if sim.engine == "numerical" and partial:
        return "closed_form+numerical"
    return sim.engine


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
