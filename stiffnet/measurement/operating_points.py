"""The campaign's own operating points as the training world of the loop's models.

A contact law that is not a linear spring makes the window's shape depend on how far
each impact goes into the contact, i.e. on the impact speed; the GBM's and the CNN's
inputs are gain-free (each window is standardised), so across operating points the same
shape can come from a soft stop hit hard and a stiff one hit gently. Measured on the
example campaign with a two-stage law (the loop's learned law, GBM): trained over the
ideal sweep the model read 0.375 of the eight recordings in class at 60 trajectories and
0.875 at 300; over the campaign's operating envelope (:mod:`.envelope`, the columns'
ranges drawn independently) 0.625; trained at one operating point it read the recordings
made there right and the others wrong.

:func:`operating_point_dataset` therefore draws each trajectory at one of the manifest's
rows (gap, forcing amplitude and frequency ratio, damping, fs/f_n and noise together,
each jittered by :data:`JITTER`), β over the whole sweep (every class at every point)
and the effects over their priors: the model learns the law at the amplitudes the
campaign has. The model's inputs are unchanged, so the predictor reads it as any other;
it is a model *of this campaign* and says so in its data card (``operating_points``).

On request (``edge_share``) a share of each point's trajectories is drawn near the class
edges (:func:`class_edges`, β within ±:data:`EDGE_WIDTH` of each, as many on either
side): a campaign's recording a few per cent from an edge is classed by where the model
puts that edge at that operating point, and a stratified sweep gives that place a handful
of trajectories. The manifest's β is never read (it is the truth being scored). It is off
by default: on the independent rig's 24-recording two-stage campaign (shared batches, three
dataset seeds) it raised the GBM's accuracy from 0.847 to 0.875 on average, but with the
CNN (dataset seeds 0 and 1) it read 20 and 18 of 24 where the defaults read 20 and 20, and
on 16 two-stage recordings (the example campaign's eight points, two betas each) the GBM
read 12 of 16 where the defaults read at least 14.

Every shard (a point, an edge at a point) is simulated in shared batches
(:data:`SHARED_BATCHES`, :func:`stiffnet.dataset.generate.simulate_shards`): with the
numerical engine a batch costs its steps, whatever its rows, and a campaign of 24 points
splits 400 trajectories into shards of about 17 (3.4x less CPU on the rig's two-stage
campaign: 430.8 -> 125.6 s). Each shard draws its plan, initial states, effect parameters
and noise from its own generator exactly as alone. The numerical engine ties a batch's rows
(its transient's step count and the record's substep are the batch's), so 5.1 % of the
windows at the rig's points moved by more than the noise std where the shared batch put a
row on another step; but a shard simulated alone is as much an accident of its batch (the
same 17 rows as 9 + 8: three moved by 13-116 noise stds), so neither is the truer
dataset. The retrained models read the rig's campaign alike either way (dataset seeds 0 and
1: GBM 0.792 / 0.792 and 0.833 / 0.875 shared / alone, CNN 0.833 / 0.833 on seed 1), for a
third of the dataset's CPU. ``shared_batches=False`` simulates each shard alone.
On request (``weights="small_gaps"``) the points do not share the trajectories evenly: a
point whose gap is below the campaign's median gets ``median / gap`` times as many (at most
:data:`MAX_WEIGHT` times), the total unchanged (:func:`point_weights`,
:func:`split_weighted`). The misses of the models retrained on the independent rig's
two-stage campaign sit at its 0.5-1.2 mm gaps, where the stop is hit hardest and the
impact reaches furthest into the law. Off by default (:data:`WEIGHTS`): on that campaign
(shared batches, dataset seeds 0 and 1) it read 17 and 18 of 24 in class with the GBM where
the even split read 19 and 20, and 19 and 19 with the CNN where the even split read 20 and
20; the small-gap points kept their misses. There the training windows at 1.2 mm are all
on the recordings' orbit (one impact per forcing period): the misses are the model's
resolution at that point, not its training world's orbits.
On request (``orbits``, :func:`hold_orbit`) each row's windows are held on its recording's
orbit (impacts per forcing period as ``analyze`` names it): windows on another orbit are
dropped where at least :data:`MIN_ON_ORBIT` of the shard reach the recording's. Off by
default (:data:`HOLD_ORBITS`): on the rig's two-stage campaign (dataset seeds 0 and 1) the CNN
read 19 and 19 of 24 where the plain dataset read 20 and 20 (the GBM 20 and 20 against 19
and 20), and the 0.5 mm β 61 recording, on one impact per period, read lower, not higher:
there the hold keeps the draws whose jittered forcing ratio lies away from the recording's
(one impact per period is reached below it), so it moves the training world off the
recording's point as much as onto its orbit.
The points' configs integrate the record no finer than the transient
(:data:`RECORD_SUBSTEPS`, ``SolverSettings.record_substeps``): the campaign's rates (a few
hundred samples per natural period) would otherwise take 8 RK4 substeps per sample, 2.5-5
times finer than the transient; the records start from the same state and move by RK4's
error there (2 of 200 windows beyond the noise, at most 1.4 times its std; the same impact
counts), 1.3-1.5x less CPU per point on a quiet machine (1 and 2 kHz).
Numbers: docs/measurement_loop.md, "Training at the campaign's operating points",
"The loop's default path on the rig's two-stage campaign", "Where a loop iteration's
dataset spends its CPU" and "The loop's second iteration, the orbit hold and the jitter".
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from stiffnet.config.sim import SimulationConfig
from stiffnet.errors import StiffnetError
from stiffnet.measurement.envelope import COLUMNS, campaign_envelope

#: The shipped settings (under ``configs/``).
OPERATING_POINTS_CONFIG = "operating_points.yaml"
#: Rules giving each row's point its share of the trajectories (:func:`point_weights`).
WEIGHT_RULES = ("none", "small_gaps")


class OperatingPointSettings(BaseModel):
    """The training world at the campaign's operating points (``configs/operating_points.yaml``;
    the measurements behind each default are in the module's notes).

    Attributes
    ----------
    jitter : float
        Relative jitter of each row's values (of the value itself; a zero gap stays zero), so
        the model does not learn one exact point and a manifest's small errors stay inside.
    edge_share : float
        Share of each point's trajectories drawn near the class edges, the rest over the sweep.
    edge_width : float
        Relative half-width ``w`` of the band around a class edge ``e``: β in
        ``[e / (1 + w), e (1 + w)]``.
    weights : {"none", "small_gaps"}
        The rule giving each row's point its share of the trajectories.
    max_weight : float
        Largest share a point gets under ``small_gaps``, relative to a point at the median gap.
    record_substeps : {"sample", "transient"}
        The record's RK4 substep at every point (``SolverSettings.record_substeps``).
    shared_batches : bool
        Simulate the points' shards together.
    hold_orbits : bool
        Hold each row's training windows on its recording's orbit (:func:`hold_orbit`).
    min_on_orbit : float
        Least share of a shard's windows on the recording's orbit for the hold to drop the
        others: below it the world rarely reaches that orbit at the point, and the shard is
        kept whole.
    trajectories : int
        Trajectories of a loop iteration's dataset at the operating points, unless the user
        gives a number (``loop --n-trajectories``); at least the loop's fewest
        (:data:`stiffnet.measurement.loop.MIN_TRAJECTORIES`).
    """

    model_config = ConfigDict(extra="forbid")

    jitter: float = Field(0.05, ge=0.0, lt=0.5)
    edge_share: float = Field(0.0, ge=0.0, le=1.0)
    edge_width: float = Field(0.2, gt=0.0, lt=1.0)
    weights: Literal["none", "small_gaps"] = "none"
    max_weight: float = Field(2.0, ge=1.0, le=10.0)
    record_substeps: Literal["sample", "transient"] = "transient"
    shared_batches: bool = True
    hold_orbits: bool = False
    min_on_orbit: float = Field(0.25, gt=0.0, le=1.0)
    trajectories: int = Field(1600, ge=50, le=10_000_000)


@lru_cache(maxsize=1)
def operating_point_settings() -> OperatingPointSettings:
    """The shipped settings: ``configs/operating_points.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(OperatingPointSettings, OPERATING_POINTS_CONFIG)


_SETTINGS = operating_point_settings()
#: Relative jitter of each row's values (``configs/operating_points.yaml``).
JITTER = _SETTINGS.jitter
#: Share of each point's trajectories drawn near the class edges (off by default: see the
#: module's notes).
EDGE_SHARE = _SETTINGS.edge_share
#: Relative half-width of the band around a class edge.
EDGE_WIDTH = _SETTINGS.edge_width
#: The rule the loop uses to share the trajectories among the points (see the module's notes).
WEIGHTS = _SETTINGS.weights
#: Largest share a point gets under ``small_gaps``.
MAX_WEIGHT = _SETTINGS.max_weight
#: The record's RK4 substep at every point (see the module's notes).
RECORD_SUBSTEPS = _SETTINGS.record_substeps
#: Simulate the points' shards together (see the module's notes).
SHARED_BATCHES = _SETTINGS.shared_batches
#: Hold each row's training windows on its recording's orbit (see the module's notes).
HOLD_ORBITS = _SETTINGS.hold_orbits
#: Least share of a shard's windows on the recording's orbit for the hold to drop the others.
MIN_ON_ORBIT = _SETTINGS.min_on_orbit
#: Trajectories of a loop iteration's dataset at the operating points (see the module's notes).
TRAJECTORIES = _SETTINGS.trajectories


def split_evenly(n: int, k: int) -> list[int]:
    """``n`` trajectories over ``k`` operating points, the first ``n mod k`` one more."""
    return [n // k + (i < n % k) for i in range(k)]


def split_weighted(n: int, weights: Sequence[float]) -> list[int]:
    """``n`` trajectories over points in proportion to ``weights`` (largest remainders, ties
    to the first points; equal weights give :func:`split_evenly`), at least one each where
    ``n`` allows."""
    w = np.asarray(weights, dtype=float)
    if w.size == 0 or np.any(w <= 0) or not np.all(np.isfinite(w)):
        raise StiffnetError(f"point weights must be positive and finite, got {list(weights)}")
    k = w.size
    if n < k or np.all(w == w[0]):
        return split_evenly(n, k)
    # one each first, so that no point is left without trajectories
    quota = (n - k) * w / w.sum()
    sizes = 1 + np.floor(quota).astype(int)
    rest = n - int(sizes.sum())
    order = np.argsort(-(quota - np.floor(quota)), kind="stable")
    sizes[order[:rest]] += 1
    return [int(x) for x in sizes]


def point_weights(rows: Sequence[Any], rule: str = WEIGHTS) -> list[float]:
    """Each row's weight in the split of the trajectories, by ``rule``.

    ``none``: equal. ``small_gaps``: ``median gap / gap``, clipped to ``[1, MAX_WEIGHT]``:
    a point whose stop is closer than the campaign's median is hit harder, reaches further
    into a nonlinear law, and there the window's shape changes most with the impact (the
    misses of the models retrained on the rig's two-stage campaign sat at its 0.5-1.2 mm
    gaps). A row without a positive gap keeps weight 1.
    """
    if rule not in WEIGHT_RULES:
        raise StiffnetError(f"point weights must be one of {', '.join(WEIGHT_RULES)}, got {rule}")
    if rule == "none":
        return [1.0] * len(rows)
    gaps = [getattr(r, "gap", None) for r in rows]
    known = [float(g) for g in gaps if g is not None and g > 0]
    if not known:
        return [1.0] * len(rows)
    median = float(np.median(known))
    return [
        float(np.clip(median / g, 1.0, MAX_WEIGHT)) if g is not None and g > 0 else 1.0
        for g in gaps
    ]


def class_edges(cfg: SimulationConfig) -> list[float]:
    """The edges between ``cfg``'s consecutive classes that lie inside its β sweep."""
    lo, hi = cfg.sweep.beta
    return [c.beta[1] for c in cfg.classes[:-1] if lo < c.beta[1] < hi]


def edge_configs(
    point_cfg: SimulationConfig, n: int, width: float = EDGE_WIDTH
) -> list[SimulationConfig]:
    """``n`` trajectories of one point near its class edges: one config per edge (the first
    ``n mod k`` one more), β stratified over ``[e / (1 + width), e (1 + width)]`` (clipped to
    the sweep), so half fall on either side; an edge left without trajectories is dropped."""
    edges = class_edges(point_cfg)
    if n < 1 or not edges:
        return []
    lo, hi = point_cfg.sweep.beta
    out = []
    for e, k in zip(edges, split_evenly(n, len(edges)), strict=True):
        if k < 1:
            continue
        sweep = point_cfg.sweep.model_copy(
            update={
                "beta": (max(lo, e / (1 + width)), min(hi, e * (1 + width))),
                "beta_sampling": "stratified",
            }  # fmt: skip
        )
        out.append(point_cfg.model_copy(update={"sweep": sweep, "n_trajectories": k}))
    return out


def operating_point_configs(
    cfg: SimulationConfig,
    rows: Sequence[Any],
    jitter: float = JITTER,
    edge_share: float = EDGE_SHARE,
    weights: str = WEIGHTS,
) -> list[SimulationConfig]:
    """The configs of the rows' points, one list (see :func:`point_config_groups`)."""
    return [c for group in point_config_groups(cfg, rows, jitter, edge_share, weights)
            for c in group]  # fmt: skip


def point_config_groups(
    cfg: SimulationConfig,
    rows: Sequence[Any],
    jitter: float = JITTER,
    edge_share: float = EDGE_SHARE,
    weights: str = WEIGHTS,
) -> list[list[SimulationConfig]]:
    """The configs of the rows' points, one list per row: ``cfg`` with its sweep at the row's
    point, ±``jitter``, then the row's near-edge configs.

    β, the classes, the effects and the windows are ``cfg``'s, its solver with the record
    at the transient's substep (:data:`RECORD_SUBSTEPS`). Each row's share of
    ``cfg.n_trajectories`` (:func:`split_evenly`) is split: ``edge_share`` of it near the
    class edges (:func:`edge_configs`, listed after the row's own config), the rest over
    ``cfg``'s β sweep. All configs share one ``shard_size`` (the largest count), so that
    the trajectory numbers of their shards never collide.
    """
    if not rows:
        raise StiffnetError("the campaign has no rows: no operating points to train at")
    if not 0.0 <= jitter < 1.0:
        raise StiffnetError(f"operating-point jitter must be in [0, 1), got {jitter}")
    if not 0.0 <= edge_share < 1.0:
        raise StiffnetError(f"share of trajectories near class edges must be in [0, 1), "
                            f"got {edge_share}")  # fmt: skip
    sizes = split_weighted(cfg.n_trajectories, point_weights(rows, weights))
    if min(sizes) < 1:
        raise StiffnetError(
            f"{cfg.n_trajectories} trajectories cannot cover {len(rows)} operating points "
            "(at least one each)"
        )
    groups = []
    solver = cfg.solver.model_copy(update={"record_substeps": RECORD_SUBSTEPS})
    for row, n in zip(rows, sizes, strict=True):
        point = campaign_envelope(cfg, [row], jitter).model_copy(update={"solver": solver})
        n_edge = int(edge_share * n)
        groups.append([point.model_copy(update={"n_trajectories": n - n_edge}),
                       *edge_configs(point, n_edge)])  # fmt: skip
    size = max(c.n_trajectories for g in groups for c in g)
    return [[c.model_copy(update={"shard_size": size}) for c in g] for g in groups]


def measured_orbits(campaign: Any) -> list[tuple[int, int] | None]:
    """Each recording's orbit ``(n, m)`` as ``analyze`` and ``diagnose`` name it (None: no
    repeating pattern, no impacts or a record that cannot be analysed)."""
    from stiffnet.measurement.orbits import orbit_pattern
    from stiffnet.measurement.target import measured_statistics

    stats, _, _ = measured_statistics(campaign, inclination=False)
    return [orbit_pattern(s) for s in stats]


def hold_orbit(
    table: Any, orbit: tuple[int, int] | None, min_share: float = MIN_ON_ORBIT
) -> tuple[Any, dict[str, Any]]:
    """A shard's windows held on its recording's orbit: those on another dropped.

    At a point where the forcing's jitter straddles a change of orbit, the training world
    mixes orbits the recording is not on (on the independent rig's 0.5 mm point, 36-47 of
    96 windows with β 35-100 shared the recording's one impact per period). The hold keeps
    the windows on ``orbit`` when at least ``min_share`` of the shard's windows reach it;
    a recording without a repeating orbit (``orbit`` None) or a world that rarely reaches it
    keeps the shard whole. Returns the table and what was done (counts, ``held``).
    """
    from stiffnet.measurement.orbits import window_orbits

    n = table.num_rows
    if orbit is None or n == 0:
        return table, {"orbit": None, "windows": n, "on_orbit": None, "held": False}
    on = np.array([o == tuple(orbit) for o in window_orbits(table)], dtype=bool)
    held = bool(on.mean() >= min_share and not on.all())
    info = {"orbit": list(orbit), "windows": n, "on_orbit": int(on.sum()), "held": held}
    return (table.filter(on) if held else table), info


def operating_point(row: Any) -> dict[str, Any]:
    """A row's point as the card lists it: its recording and each sweep column's value."""
    point = {col: get(row) for col, get in COLUMNS.items()}
    return {"recording": str(getattr(row, "recording", "")), **point}


def operating_point_dataset(
    cfg: SimulationConfig,
    rows: Sequence[Any],
    out: str | Path,
    jitter: float = JITTER,
    edge_share: float = EDGE_SHARE,
    progress: Callable[[int, int], None] | None = None,
    shared_batches: bool = SHARED_BATCHES,
    weights: str = WEIGHTS,
    orbits: Sequence[tuple[int, int] | None] | None = None,
) -> dict[str, Any]:
    """Simulate ``cfg.n_trajectories`` trajectories at the rows' operating points into ``out``.

    Each config of :func:`operating_point_configs` is one shard (a row's point over the
    sweep, then its trajectories near the class edges), each simulated (or all together in
    shared batches, ``shared_batches``) and written as
    :func:`stiffnet.dataset.generate.generate_dataset` does; the data card, written last,
    is that of the rows' envelope (the box around every point, widened by ``jitter``)
    with the points and the edge draws under ``operating_points``.

    Parameters
    ----------
    cfg : SimulationConfig
        The training world (β sweep, classes, effects with their priors, windows, seed).
    rows : sequence of ManifestRow
        The campaign's rows (a column a row lacks keeps ``cfg``'s range at that point).
    out : str or Path
        A new or empty folder.
    jitter : float
        Relative jitter of each row's values.
    edge_share : float
        Share of each point's trajectories drawn near the class edges.
    progress : callable, optional
        ``progress(done, total)`` in shards.
    shared_batches : bool
        Simulate every shard in shared batches (see the module's notes).
    weights : str
        The rule of each point's share of the trajectories (:func:`point_weights`).
    orbits : sequence, optional
        Each row's measured orbit (:func:`measured_orbits`): its shards' windows are held on
        it (:func:`hold_orbit`). Default: no hold.

    Returns
    -------
    dict
        The data card.
    """
    from stiffnet.dataset.generate import (
        ShardJob,
        config_fingerprint,
        dataset_card,
        run_shard_job,
        simulate_shard,
        simulate_shards,
        write_shard_table,
    )
    from stiffnet.dataset.store import write_card
    from stiffnet.io_utils import output_lock

    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise StiffnetError(f"output folder {out} exists and is not empty")
    groups = point_config_groups(cfg, rows, jitter, edge_share, weights)
    configs = [c for g in groups for c in g]
    row_of = [i for i, g in enumerate(groups) for _ in g]
    if orbits is not None and len(orbits) != len(rows):
        raise StiffnetError(f"{len(orbits)} measured orbits for {len(rows)} rows")
    t0 = time.perf_counter()
    records, holds = [], []
    with output_lock(out):
        tables = simulate_shards(configs, list(range(len(configs)))) if shared_batches else None
        seconds = (time.perf_counter() - t0) / len(configs)
        for i, point_cfg in enumerate(configs):
            job = ShardJob(point_cfg, str(out.resolve()), i, point_cfg.n_trajectories,
                           config_fingerprint(point_cfg))  # fmt: skip
            if orbits is None:
                records.append(
                    write_shard_table(job, tables[i], seconds) if tables else run_shard_job(job)
                )
            else:
                t1 = time.perf_counter()
                table = tables[i] if tables else simulate_shard(point_cfg, i, job.n)
                table, info = hold_orbit(table, orbits[row_of[i]])
                holds.append({"shard": i, "row": row_of[i], **info})
                records.append(write_shard_table(
                    job, table, seconds if tables else time.perf_counter() - t1))  # fmt: skip
            if progress:
                progress(i + 1, len(configs))
        box = campaign_envelope(cfg, rows, jitter)
        card = dataset_card(box, records, time.perf_counter() - t0)
        card["operating_points"] = {
            "jitter": jitter,
            "edge_share": edge_share,
            "weights": weights,
            "trajectories": [c.n_trajectories for c in configs],
            "edge_width": EDGE_WIDTH,
            "class_edges": class_edges(cfg),
            "points": [operating_point(r) for r in rows],
            "orbit_hold": holds if orbits is not None else None,
        }
        write_card(out, card)
    return card
