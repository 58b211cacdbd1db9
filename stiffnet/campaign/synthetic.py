"""Synthetic campaigns: a manifest of parameters -> a campaign folder of simulated
recordings (``stiffnet simulate-campaign``).

The folder has the layout of a real campaign (``manifest.csv`` and the recordings
under their relative names) plus ``campaign_card.json``, the ground truth a real
campaign would not tell (effects, their per-recording drawn values, gains, seed,
stiffnet version). Each row is one task (:func:`stiffnet.campaign.simulate.simulate_row`)
of :mod:`stiffnet.distributed`; the files are written here, on the caller's side.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import secrets
import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from stiffnet.campaign.manifest import (
    CARD_NAME,
    MANIFEST_NAME,
    READ_COLUMNS,
    ManifestRow,
    read_manifest_with_columns,
    write_manifest,
)
from stiffnet.campaign.simulate import RowJob, check_rows, simulate_row
from stiffnet.distributed.cluster import check_target
from stiffnet.distributed.tasks import run_tasks
from stiffnet.effects.base import Effect
from stiffnet.effects.registry import build_effect, parse_effect_option
from stiffnet.errors import StiffnetError
from stiffnet.io_utils import check_replaceable_folder, new_marker, output_lock
from stiffnet.progress import task as progress_task
from stiffnet.recordings import write_recording_csv


def simulate_campaign(
    manifest_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    effects: Sequence[Effect | str] = (),
    seed: int = 0,
    default_duration_s: float = 10.0,
    overwrite: bool = False,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
) -> Path:
    """Simulate one recording per manifest row: a synthetic campaign.

    Each row needs ``beta``, ``gap``, ``amplitude``, ``frequency_ratio`` and
    ``damping_ratio``; ``natural_frequency_hz`` defaults to the paper's
    9.48 Hz, ``duration_s`` to ``default_duration_s`` and ``noise`` to
    :data:`DEFAULT_NOISE`. Rows are simulated one at a time by
    :class:`~stiffnet.simulator.Simulator` with the given effects, sampled at
    ``fs_hz`` (``fs_ratio = fs_hz / f_n``), and written in g (see
    :func:`sensor_gain`) under the row's relative name (``.csv`` as ``t,accel``,
    or ``.npy``).

    The output folder holds the recordings, ``manifest.csv`` (the input's
    columns and values) and ``campaign_card.json`` (the ground truth a real
    campaign would not tell: effects, their per-recording drawn values, gains,
    seed, stiffnet version). It is built in a hidden sibling folder and moved
    into place at the end, so an interrupted run leaves nothing that looks
    complete.

    Parameters
    ----------
    manifest_path : str or os.PathLike
        Input manifest (its recordings need not exist).
    out_dir : str or os.PathLike
        Folder to create.
    effects : sequence of Effect or str
        Effects to simulate with; a string is parsed as ``NAME[:k=v,...]``.
    seed : int
        Base seed. Each row draws from ``(seed, crc32(recording))``: the same
        seed gives identical files, whatever the order of the rows.
    default_duration_s : float
        Duration of rows without ``duration_s``.
    overwrite : bool
        Replace ``out_dir`` if it exists and is not empty.
    scheduler, workers : str or None, int or None
        Simulate the rows as Dask tasks on this scheduler, or on a LocalCluster of
        this many worker processes (see :mod:`stiffnet.distributed`); by default
        in-process. The files are the same either way: a row depends only on
        ``(seed, recording)``, and the recordings are written here, not on workers.

    Returns
    -------
    pathlib.Path
        ``out_dir``.
    """
    manifest = Path(manifest_path)
    out = Path(out_dir).resolve()  # a real name and parent, even for "." or "a/.."
    if not isinstance(seed, int | np.integer) or isinstance(seed, bool) or seed < 0:
        raise StiffnetError(f"seed must be a non-negative integer, got {seed!r}")
    if not (math.isfinite(default_duration_s) and default_duration_s > 0):
        raise StiffnetError(f"default_duration_s must be > 0, got {default_duration_s}")
    check_target(scheduler, workers)
    columns, rows = read_manifest_with_columns(manifest)
    with output_lock(out):  # one writer per folder: a concurrent run is refused
        _check_out_dir(out, manifest, overwrite)
        _simulate_into(manifest, out, columns, rows, effects, seed, default_duration_s,
                       scheduler, workers)  # fmt: skip
    return Path(out_dir)


def _simulate_into(
    manifest: Path,
    out: Path,
    columns: list[str],
    rows: list[ManifestRow],
    effects: Sequence[Effect | str],
    seed: int,
    default_duration_s: float,
    scheduler: str | None,
    workers: int | None,
) -> None:
    from stiffnet import __version__
    from stiffnet.simulator.compiled import limited_threads

    eff = [build_effect(*parse_effect_option(e)) if isinstance(e, str) else e for e in effects]

    # Check every row before simulating anything.
    check_rows(rows, manifest)
    for row in rows:
        if Path(row.recording).suffix.lower() not in (".csv", ".npy"):
            raise StiffnetError(
                f"{row.where(manifest)}: simulated recordings are .csv or .npy files"
            )
        if row.recording in (MANIFEST_NAME, CARD_NAME):
            raise StiffnetError(f"{row.where(manifest)}: {row.recording} is a reserved name")
        duration = row.duration_s or default_duration_s
        if round(duration * row.fs_hz) < 2:
            raise StiffnetError(f"{row.where(manifest)}: duration_s * fs_hz is under 2 samples")

    # Simulate first (rows as tasks, results back here), then write: workers need no
    # access to the output folder, and a failed row leaves nothing behind.
    jobs = [RowJob(row, eff, int(seed), default_duration_s, row.where(manifest)) for row in rows]
    with progress_task("simulating recordings", len(jobs)) as bar:
        report = run_tasks(simulate_row, jobs, scheduler=scheduler, workers=workers,
                           names=[row.recording for row in rows], thread_limit=limited_threads,
                           progress=lambda done, _: bar.update(done))  # fmt: skip
    if report.failed:
        name, msg = next(iter(report.failed.items()))
        raise StiffnetError(msg) from report.errors.get(name)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.{secrets.token_hex(4)}.partial"
    tmp.mkdir()
    try:
        card_rows = []
        for row, (accel, card_row) in zip(rows, report.results, strict=True):
            target = tmp / row.recording
            if target.suffix.lower() == ".npy":
                target.parent.mkdir(parents=True, exist_ok=True)
                np.save(target, accel)
            else:
                write_recording_csv(target, accel, row.fs_hz)
            card_rows.append(card_row)
        # simulated CSVs are written as t,accel in seconds: drop the input's read options
        plain = [r.model_copy(update=dict.fromkeys(READ_COLUMNS)) for r in rows]
        write_manifest(tmp / MANIFEST_NAME, plain, [c for c in columns if c not in READ_COLUMNS])
        card = {
            "stiffnet_version": __version__,
            "generator": "stiffnet.campaign.simulate_campaign",
            "source_manifest": manifest.name,
            "seed": int(seed),
            "default_duration_s": default_duration_s,
            "accel_unit": "g, for a model length unit of 1 mm (sensor_gain = model to g)",
            "effects": [
                {
                    "name": e.name,
                    "class": f"{type(e).__module__}:{type(e).__qualname__}",
                    "kind": e.kind,
                    "params": e.params.model_dump(),
                }
                for e in eff
            ],
            "recordings": card_rows,
        }
        # the marker --overwrite trusts: a stiffnet kind and a run id, here a hash of the
        # card, so that the same inputs still give a byte-identical campaign
        digest = hashlib.sha256(json.dumps(card, sort_keys=True).encode()).hexdigest()[:32]
        card = {**new_marker("stiffnet-campaign"), "run_id": digest, **card}
        (tmp / CARD_NAME).write_text(json.dumps(card, indent=2) + "\n", encoding="utf-8")
        _swap_in(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _check_out_dir(out: Path, manifest: Path, overwrite: bool) -> None:
    if not out.exists():
        return
    if not out.is_dir():
        raise StiffnetError(f"{out}: exists and is not a folder")
    if not any(out.iterdir()):
        return
    if not overwrite:
        raise StiffnetError(f"{out}: folder exists and is not empty (use overwrite to replace it)")
    if manifest.resolve().is_relative_to(out.resolve()):
        raise StiffnetError(f"{out}: refusing to overwrite the folder holding the input manifest")
    check_replaceable_folder(out, (CARD_NAME,))  # only a campaign stiffnet wrote is replaced


def _swap_in(tmp: Path, out: Path) -> None:
    """Move the finished ``tmp`` folder to ``out``, replacing what is there."""
    if not out.exists():
        os.replace(tmp, out)
        return
    old = out.parent / f".{out.name}.{secrets.token_hex(4)}.old"
    os.replace(out, old)
    try:
        os.replace(tmp, out)
    except BaseException:
        os.replace(old, out)
        raise
    shutil.rmtree(old, ignore_errors=True)
