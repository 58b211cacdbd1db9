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


def split_evenly(n: int, k: int) -> list[int]:
    """``n`` trajectories over ``k`` operating points, the first ``n mod k`` one more."""
    return [n // k + (i < n % k) for i in range(k)]


def operating_point_configs(
    cfg: SimulationConfig, rows: Sequence[Any], jitter: float = JITTER
) -> list[SimulationConfig]:
    """One config per manifest row: ``cfg`` with its sweep at the row's point, ±``jitter``.

    β, the classes, the effects and the windows are ``cfg``'s; each config's
    ``n_trajectories`` is its share of ``cfg.n_trajectories`` (:func:`split_evenly`) and
    all share one ``shard_size`` (the largest share), so that the trajectory numbers of
    the shards never collide.
    """
    if not rows:
        raise StiffnetError("the campaign has no rows: no operating points to train at")
    if not 0.0 <= jitter < 1.0:
        raise StiffnetError(f"operating-point jitter must be in [0, 1), got {jitter}")
    sizes = split_evenly(cfg.n_trajectories, len(rows))
    if min(sizes) < 1:
        raise StiffnetError(
            f"{cfg.n_trajectories} trajectories cannot cover {len(rows)} operating points "
            "(at least one each)"
        )
    size = max(sizes)
    return [
        campaign_envelope(cfg, [row], jitter).model_copy(
            update={"n_trajectories": n, "shard_size": size}
        )
        for row, n in zip(rows, sizes, strict=True)
    ]


def operating_point(row: Any) -> dict[str, Any]:
    """A row's point as the card lists it: its recording and each sweep column's value."""
    point = {col: get(row) for col, get in COLUMNS.items()}
    return {"recording": str(getattr(row, "recording", "")), **point}


def operating_point_dataset(
    cfg: SimulationConfig,
    rows: Sequence[Any],
    out: str | Path,
    jitter: float = JITTER,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Simulate ``cfg.n_trajectories`` trajectories at the rows' operating points into ``out``.

    Shard ``i`` holds the trajectories of row ``i`` (:func:`operating_point_configs`),
    each simulated and written as :func:`stiffnet.dataset.generate.generate_dataset`
    does; the data card, written last, is that of the rows' envelope (the box around
    every point, widened by ``jitter``) with the list of points under
    ``operating_points``.

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
    progress : callable, optional
        ``progress(done, total)`` in shards.

    Returns
    -------
    dict
        The data card.
    """
    from stiffnet.dataset.generate import ShardJob, config_fingerprint, dataset_card, run_shard_job
    from stiffnet.dataset.store import write_card
    from stiffnet.io_utils import output_lock

    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise StiffnetError(f"output folder {out} exists and is not empty")
    configs = operating_point_configs(cfg, rows, jitter)
    t0 = time.perf_counter()
    records = []
    with output_lock(out):
        for i, point_cfg in enumerate(configs):
            job = ShardJob(point_cfg, str(out.resolve()), i, point_cfg.n_trajectories,
                           config_fingerprint(point_cfg))  # fmt: skip
            records.append(run_shard_job(job))
            if progress:
                progress(i + 1, len(configs))
        box = campaign_envelope(cfg, rows, jitter)
        card = dataset_card(box, records, time.perf_counter() - t0)
        card["operating_points"] = {"jitter": jitter, "points": [operating_point(r) for r in rows]}
        write_card(out, card)
    return card
