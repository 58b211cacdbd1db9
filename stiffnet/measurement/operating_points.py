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
dataset seeds) it raised the accuracy from 0.847 to 0.875 on average, but on 16 two-stage
recordings (the example campaign's eight points, two betas each) it read 12 of 16 where the
defaults read at least 14.

On request (``shared_batches``) every shard (a point, an edge at a point) is simulated in
shared batches (:func:`stiffnet.dataset.generate.simulate_shards`): with the numerical
engine a batch costs its steps, whatever its rows, and a campaign of 24 points splits 400
trajectories into shards of about 17 (4.2x less CPU on six of them). Off by default: its
draws of the initial states differ, and with them the retrained GBM read the loop test's 8
two-stage recordings 7 of 8, and 16 (the example campaign's eight points, two betas each)
13 of 16 in class where the per-shard draws read at least 14.
Numbers: docs/measurement_loop.md, "Training at the campaign's operating points".
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from stiffnet.config.sim import SimulationConfig
from stiffnet.errors import StiffnetError
from stiffnet.measurement.envelope import COLUMNS, campaign_envelope

#: Relative jitter of each row's values (of the value itself; a zero gap stays zero), so
#: the model does not learn one exact point and a manifest's small errors stay inside.
JITTER = 0.05
#: Share of each point's trajectories drawn near the class edges, the rest over the sweep
#: (off by default: see the module's docstring).
EDGE_SHARE = 0.0
#: Relative half-width of the band around a class edge ``e``: β in ``[e / (1 + w), e (1 + w)]``.
EDGE_WIDTH = 0.2


def split_evenly(n: int, k: int) -> list[int]:
    """``n`` trajectories over ``k`` operating points, the first ``n mod k`` one more."""
    return [n // k + (i < n % k) for i in range(k)]


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
) -> list[SimulationConfig]:
    """The configs of the rows' points: ``cfg`` with its sweep at each row's point, ±``jitter``.

    β, the classes, the effects and the windows are ``cfg``'s. Each row's share of
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
    sizes = split_evenly(cfg.n_trajectories, len(rows))
    if min(sizes) < 1:
        raise StiffnetError(
            f"{cfg.n_trajectories} trajectories cannot cover {len(rows)} operating points "
            "(at least one each)"
        )
    configs = []
    for row, n in zip(rows, sizes, strict=True):
        point = campaign_envelope(cfg, [row], jitter)
        n_edge = int(edge_share * n)
        configs.append(point.model_copy(update={"n_trajectories": n - n_edge}))
        configs.extend(edge_configs(point, n_edge))
    size = max(c.n_trajectories for c in configs)
    return [c.model_copy(update={"shard_size": size}) for c in configs]


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
    shared_batches: bool = False,
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
        simulate_shards,
        write_shard_table,
    )
    from stiffnet.dataset.store import write_card
    from stiffnet.io_utils import output_lock

    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise StiffnetError(f"output folder {out} exists and is not empty")
    configs = operating_point_configs(cfg, rows, jitter, edge_share)
    t0 = time.perf_counter()
    records = []
    with output_lock(out):
        tables = simulate_shards(configs, list(range(len(configs)))) if shared_batches else None
        seconds = (time.perf_counter() - t0) / len(configs)
        for i, point_cfg in enumerate(configs):
            job = ShardJob(point_cfg, str(out.resolve()), i, point_cfg.n_trajectories,
                           config_fingerprint(point_cfg))  # fmt: skip
            records.append(
                write_shard_table(job, tables[i], seconds) if tables else run_shard_job(job)
            )
            if progress:
                progress(i + 1, len(configs))
        box = campaign_envelope(cfg, rows, jitter)
        card = dataset_card(box, records, time.perf_counter() - t0)
        card["operating_points"] = {
            "jitter": jitter,
            "edge_share": edge_share,
            "edge_width": EDGE_WIDTH,
            "class_edges": class_edges(cfg),
            "points": [operating_point(r) for r in rows],
        }
        write_card(out, card)
    return card
