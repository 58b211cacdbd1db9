"""Batch prediction (``predict-batch``): many recordings, one Parquet table, parts
computed as tasks of :mod:`stiffnet.distributed` (in-process or on Dask).

Recordings are sorted by path and cut into parts of ``part_size``; each part is one
task that loads the predictor (once per worker process), predicts its recordings
and writes ``OUT.parts/part-NNNNN.parquet`` atomically, then its record
``part-NNNNN.json`` (rows, SHA-256, fingerprint of the part's inputs). When every
part exists, they are concatenated into ``OUT`` (atomically) and the parts folder is
removed. An interrupted run resumes: parts whose record matches are kept.

Each row holds the model's answer and both cross-checks of :func:`serving.predictor.
predict_recording`: the geometric one and the restoring-force one (``restoring_force_*``).
A recording that cannot be predicted (unreadable, too short, constant...) gets a row
with its ``error`` and nulls elsewhere: one bad file never stops the batch, and the
summary names every failed recording (``failed``; the command then exits 1).

A campaign folder (one holding ``manifest.csv``, or the manifest itself) is read
through its manifest: its recordings, and per recording the columns that say how to
read it (``fs_hz``, ``natural_frequency_hz``, ``columns``, ``time_unit``,
``channel``) and the sensor chain's data sheet (``sensor``: undone as given, as
``--sensor`` or a sidecar would; ``sensor_source`` in the table); an option fills only
what the manifest leaves empty. A campaign has one accelerometer: the chains the
restoring-force check identified on its recordings (``sensor`` in the table) are pooled
(:mod:`serving.campaign_chain`) and, where they agree, every recording without its own
data sheet is predicted again in a second round of parts with the pooled chain as its
sheet, kept where it reads their contact laws about as well as the first round did (a
recording whose own law it reads much worse keeps its first row; where the pool found the
contacts' own dissipation, read with it free: the campaign is pooled and read as
``evaluate`` reads it) (``sensor_source`` ``campaign``; the summary's ``sensor`` says what
was pooled, on how many recordings, or why nothing was). A record whose
beta changes along it (several layers, :func:`serving.log.record_layers`) has them
in ``layers`` (JSON) and the alarm fired. A campaign has one rig: where its recordings
read a contact law the training data lack more often than the training world's laws do
(:mod:`stiffnet.uncertainty.campaign_law`), every row's alarm has ``campaign_law`` fired
(``alarm_fired``; the summary's ``campaign_law`` says on how many recordings the law was
judged and fired).
Workers must see the recordings and the model at the same paths (a shared file
system on a multi-machine cluster).
"""

from __future__ import annotations

import functools
import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from serving.campaign_chain import (
    chain_fitted_regardless,
    confirmed,
    dissipation_readers,
    identify_regardless,
    labelled,
    profile_readers,
    profiled_campaign_chain,
    read_through,
    reads_alone,
)
from serving.predictor import Predictor, predict_recording, record_natural_frequency
from stiffnet.distributed.cluster import check_target, dask_client
from stiffnet.distributed.tasks import run_tasks
from stiffnet.errors import RateMismatch, StiffnetError
from stiffnet.inputs import walk_files
from stiffnet.io_utils import (
    claim_parts_folder,
    remove_parts_folder,
    sha256_file,
    write_bytes_atomic,
    write_json_atomic,
)
from stiffnet.uncertainty.campaign_law import (
    CAMPAIGN_LAW,
    CONTACT_UNEXPLAINED,
    campaign_law_decision,
    contact_law_fired,
    contact_unexplained,
    law_checks_fired,
)

#: Recordings per part (one task) by default: big enough to amortise a task's
#: overhead (~10 ms) and small enough to balance a few thousand recordings.
PART_SIZE = 16


def find_recordings(spec: str | Path) -> list[Path]:
    """Recordings named by a folder (searched recursively), a glob or one file, sorted.

    Only files with an extension of a registered format
    (:func:`stiffnet.recordings.supported_extensions`) count; hidden files (temporary
    files) and campaign manifests (``manifest.csv``) are skipped.
    """
    from stiffnet.campaign import MANIFEST_NAME
    from stiffnet.recordings import supported_extensions

    extensions = supported_extensions()

    text = str(spec)
    found = walk_files(text)  # bounded: a glob over /proc is one error, not a hang
    found = [
        p for p in found
        if p.suffix.lower() in extensions and not p.name.startswith(".")
        and p.name != MANIFEST_NAME
    ]  # fmt: skip
    if not found:
        raise StiffnetError(f"no recordings found at {text} (looked for {', '.join(extensions)})")
    return sorted(found, key=str)


def campaign_inputs(
    spec: str | Path,
    fs_hz: float | None = None,
    natural_frequency_hz: float | None = None,
    columns: str | None = None,
    time_unit: str | None = None,
    channel: str | None = None,
) -> tuple[list[str], list[tuple[Any, ...]], Path, list[str | None], list[str | None]] | None:
    """A campaign folder's recordings and per-recording read settings, from its manifest.

    None when ``spec`` is not a campaign (no ``manifest.csv`` in the folder, and not a
    manifest file). The manifest's columns win; the options fill the empty ones. A row's
    settings end with its ``sensor`` data sheet (None: none in the manifest). Recording
    files that do not exist stay in the list (their rows get the error). Last, where each
    row's f_n comes from (:func:`fn_source`), and where its rate does (:func:`fs_source`).
    """
    from stiffnet.campaign import MANIFEST_NAME
    from stiffnet.campaign.manifest import read_manifest

    p = Path(spec)
    if p.is_dir() and (p / MANIFEST_NAME).is_file():
        manifest = p / MANIFEST_NAME
    elif p.is_file() and p.name == MANIFEST_NAME:
        manifest = p
    else:
        return None
    root = manifest.parent.resolve()
    paths, settings, sources, rate_sources = [], [], [], []
    for row in read_manifest(manifest):
        path = (root / row.recording).resolve()
        if not path.is_relative_to(root):
            raise StiffnetError(f"{row.where(manifest)}: recording path leaves the campaign folder")
        paths.append(str(manifest.parent / row.recording))
        settings.append(row_settings(row, fs_hz, natural_frequency_hz, columns, time_unit,
                                     channel))  # fmt: skip
        sources.append(row.natural_frequency_source(manifest) or fn_source(natural_frequency_hz))
        rate_sources.append(fs_source(row, manifest))
    return paths, settings, manifest, sources, rate_sources


def fs_source(row: Any, manifest: Path | None) -> str | None:
    """Where a recording's given rate comes from, to head a rate mismatch's message: the
    manifest line and column that give it (the place to mend), None for no row."""
    if row is None or row.fs_hz is None:
        return None
    return f"{row.where(manifest)}, column fs_hz"


def fn_source(option_hz: float | None) -> str | None:
    """Where the f_n of a recording whose row gives none comes from, as
    ``natural_frequency_source`` says it: the option; None without it (the recording's
    sidecar or its campaign's row then, as ``predict``). A row's own is
    :meth:`ManifestRow.natural_frequency_source`."""
    return None if option_hz is None else "option --fn"


def row_settings(
    row: Any,
    fs_hz: float | None = None,
    natural_frequency_hz: float | None = None,
    columns: str | None = None,
    time_unit: str | None = None,
    channel: str | None = None,
) -> tuple[Any, ...]:
    """How to read one manifest row's recording: ``(fs_hz, natural_frequency_hz, columns,
    time_unit, channel, sensor data sheet)``, the row's values where it gives them, else the
    ones passed (:func:`campaign_inputs`; ``predict`` on one recording of a campaign)."""
    return (
        row.fs_hz if row.fs_hz is not None else fs_hz,
        row.natural_frequency_hz or natural_frequency_hz,
        row.columns.replace(";", ",") if row.columns else columns,
        row.time_unit or time_unit,
        row.channel or channel,
        row.sensor_sheet(),  # the data sheet (None: the sidecar's, else fitted)
    )


def result_schema(class_names: list[str]) -> pa.Schema:
    """Columns of the batch table (one row per recording)."""
    return pa.schema(
        [
            ("path", pa.string()),
            ("class", pa.string()),
            *[(f"p_{name}", pa.float64()) for name in class_names],
            ("beta", pa.float64()),
            ("beta_low", pa.float64()),
            ("beta_high", pa.float64()),
            ("geometric_class", pa.string()),
            ("geometric_beta", pa.float64()),
            ("agreement", pa.bool_()),
            ("restoring_force_class", pa.string()),
            ("restoring_force_beta", pa.float64()),
            ("restoring_force_beta_low", pa.float64()),
            ("restoring_force_beta_high", pa.float64()),
            ("restoring_force_agreement", pa.bool_()),
            ("restoring_force_contact_r2", pa.float64()),
            ("ood_score", pa.float64()),
            ("ood_flag", pa.bool_()),
            ("alarm_fired", pa.string()),
            ("contact_law_judged", pa.bool_()),
            ("contact_unexplained", pa.bool_()),
            ("n_windows", pa.int64()),
            ("fs_hz", pa.float64()),
            ("natural_frequency_hz", pa.float64()),
            ("duration_s", pa.float64()),
            ("natural_frequency_source", pa.string()),
            ("channel", pa.string()),
            ("sensor_source", pa.string()),
            ("sensor", pa.string()),
            ("chain_readings", pa.string()),
            ("n_layers", pa.int64()),
            ("layers", pa.string()),
            ("warnings", pa.string()),
            ("error", pa.string()),
        ]
    )


def result_row(
    path: str, result: dict[str, Any] | None, error: str | None, channel: str | None = None
) -> dict[str, Any]:
    """A table row from a prediction (or from the error that prevented it)."""
    row: dict[str, Any] = {"path": path, "error": error, "channel": channel}
    if result is None:
        return row
    interval = result.get("beta_interval") or [None, None]
    restoring_force_interval = result.get("restoring_force_beta_interval") or [None, None]
    geometric = result.get("geometric") or {}
    sensor = (result.get("restoring_force") or {}).get("sensor") or {}
    row.update(
        {
            "class": result["class"],
            **{f"p_{k}": float(v) for k, v in result["probabilities"].items()},
            "beta": result.get("beta"),
            "beta_low": interval[0],
            "beta_high": interval[1],
            "geometric_class": geometric.get("class"),
            "geometric_beta": geometric.get("beta"),
            "agreement": result.get("agreement"),
            "restoring_force_class": result.get("restoring_force_class"),
            "restoring_force_beta": result.get("restoring_force_beta"),
            "restoring_force_beta_low": restoring_force_interval[0],
            "restoring_force_beta_high": restoring_force_interval[1],
            "restoring_force_agreement": result.get("restoring_force_agreement"),
            "restoring_force_contact_r2": (result.get("restoring_force") or {}).get("contact_r2"),
            "ood_score": result.get("ood_score"),
            "ood_flag": result.get("ood_flag"),
            # the alarm's checks that fired (comma-separated), and whether its contact-law
            # check could judge the recording (the campaign's law is judged on all of them)
            "alarm_fired": ",".join((result.get("alarm") or {}).get("fired") or []) or None,
            "contact_law_judged": contact_law_fired(
                result.get("alarm"), restoring_force=result.get("restoring_force")
            )[0],
            # the cross-check refused: no law it fits explains the contact force (counted
            # by the campaign's law, as the alarm's law checks are)
            "contact_unexplained": contact_unexplained(result.get("restoring_force")),
            "n_windows": result.get("n_windows"),
            "fs_hz": result.get("fs_hz"),
            "natural_frequency_hz": result.get("natural_frequency_hz"),
            "duration_s": result.get("duration_s"),
            "natural_frequency_source": result.get("natural_frequency_source"),
            # where the chain undone came from: "data sheet" or "fitted" (None: none undone)
            "sensor_source": sensor.get("source"),
            # the chain itself (JSON): the campaign pools the identified ones
            "sensor": json.dumps(sensor) if sensor else None,
            # the model's readings through the other chains a fitted one stands for (JSON):
            # what the interval spans beside the model's own reading
            "chain_readings": json.dumps(result["chain_readings"])
            if result.get("chain_readings")
            else None,
            "n_layers": len(result.get("layers") or []) or None,
            "layers": json.dumps(result["layers"]) if len(result.get("layers") or []) > 1 else None,
            "warnings": "; ".join(result.get("warnings") or []) or None,
        }
    )
    return row


@dataclass(frozen=True)
class PartJob:
    """One part: predict ``paths`` with the model at ``model_path`` into ``parts_dir``.

    ``paths`` are the names reported in the table; ``files`` the same, absolute, so a
    worker started elsewhere finds them (on a shared file system).
    """

    index: int
    paths: tuple[str, ...]
    files: tuple[str, ...]
    parts_dir: str
    model_path: str
    model_sha256: str
    class_names: tuple[str, ...]
    fs_hz: float | None
    natural_frequency_hz: float | None
    fingerprint: str
    #: CSV layout (see stiffnet.recordings.read_recording)
    columns: str | None = None
    time_unit: str | None = None
    #: per recording (a campaign's manifest): (fs_hz, natural_frequency_hz, columns,
    #: time_unit, channel, sensor data sheet), replacing the part's shared settings
    settings: tuple[tuple[Any, ...], ...] | None = None
    #: per recording: read through the campaign's pooled chain (its sheet in `settings`)
    campaign_chain: tuple[bool, ...] | None = None
    #: the recordings read through the pooled chain are read with a free ``delta v``
    #: dissipation (the chain's ``contact_dissipation``; None: as the model's law asks)
    penetration_dissipation: bool | None = None
    #: per recording: where its f_n comes from (:func:`fn_source`; None: resolved on reading)
    fn_sources: tuple[str | None, ...] | None = None
    #: per recording: the manifest line and column its rate comes from (:func:`fs_source`)
    fs_sources: tuple[str | None, ...] | None = None
    #: testing hook, called with the part index as the task starts (fault injection)
    before: Callable[[int], None] | None = None


@functools.lru_cache(maxsize=4)
def _predictor(model_path: str, sha256: str) -> Any:
    """The predictor, loaded once per process (a worker runs many parts of many runs;
    the SHA-256 in the key makes a model replaced on disk load again)."""
    predictor = Predictor.load(model_path)
    if predictor.sha256 != sha256:
        raise StiffnetError(f"{model_path} changed during the run (SHA-256)")
    return predictor


def predict_part(job: PartJob) -> dict[str, Any]:
    """Predict one part's recordings, write the part atomically, then its record."""
    if job.before is not None:
        job.before(job.index)
    t0 = time.perf_counter()
    predictor = _predictor(job.model_path, job.model_sha256)
    rows = []
    shared = (job.fs_hz, job.natural_frequency_hz, job.columns, job.time_unit, None, None)
    settings = job.settings or (shared,) * len(job.paths)
    pooled = job.campaign_chain or (False,) * len(job.paths)
    fn_sources = job.fn_sources or (None,) * len(job.paths)
    fs_sources = job.fs_sources or (None,) * len(job.paths)
    for path, file, (
        fs,
        fn,
        columns,
        time_unit,
        channel,
        sensor,
    ), from_campaign, fn_from, fs_from in zip(
        job.paths, job.files, settings, pooled, fn_sources, fs_sources, strict=True
    ):
        try:
            result = predict_recording(file, fs_hz=fs, predictor=predictor,
                                       natural_frequency_hz=fn, columns=columns,
                                       time_unit=time_unit, channel=channel,
                                       sensor=sensor, sensor_fitted=from_campaign,
                                       natural_frequency_source=fn_from,
                                       penetration_dissipation=job.penetration_dissipation
                                       if from_campaign else None)  # fmt: skip
            result = labelled(result, from_campaign)
            rows.append(result_row(path, result, None, channel))
        except RateMismatch as exc:  # the row gave the rate: say which line to mend
            where = f"{fs_from}: " if fs_from else ""
            rows.append(result_row(path, None, f"{where}{exc}", channel))
        except StiffnetError as exc:
            rows.append(result_row(path, None, str(exc), channel))
        except Exception as exc:  # noqa: BLE001 - one odd file must not stop a batch
            rows.append(result_row(path, None, f"{type(exc).__name__}: {exc}", channel))
    table = pa.Table.from_pylist(rows, schema=result_schema(list(job.class_names)))
    path = Path(job.parts_dir) / f"part-{job.index:05d}.parquet"
    write_bytes_atomic(path, _parquet_bytes(table))
    record = {
        "part": job.index,
        "file": path.name,
        "rows": table.num_rows,
        "errors": sum(r["error"] is not None for r in rows),
        "sha256": sha256_file(path),
        "fingerprint": job.fingerprint,
        "seconds": round(time.perf_counter() - t0, 3),
    }
    write_json_atomic(path.with_suffix(".json"), record)
    return record


def _parquet_bytes(table: pa.Table) -> bytes:
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    return sink.getvalue().to_pybytes()


def _finished_part(parts_dir: Path, index: int, fingerprint: str) -> dict[str, Any] | None:
    path = parts_dir / f"part-{index:05d}.parquet"
    try:
        record = json.loads(path.with_suffix(".json").read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("fingerprint") != fingerprint:
        return None
    if not path.is_file() or sha256_file(path) != record.get("sha256"):
        return None
    return record


def _fingerprint(
    paths: tuple[str, ...], model_sha256: str, fs_hz, fn, layout=(), settings=None
) -> str:
    # the table's columns too: a part written with other columns cannot be concatenated
    columns = result_schema([]).names
    data = {"paths": paths, "model": model_sha256, "fs_hz": fs_hz, "fn": fn, "columns": columns}
    if any(layout):
        data["layout"] = list(layout)
    if settings is not None:
        data["settings"] = [list(x) for x in settings]
    text = json.dumps(data)
    return hashlib.sha256(text.encode()).hexdigest()


def predict_batch(
    recordings: str | Path,
    out: str | Path,
    *,
    model_path: str | Path | None = None,
    fs_hz: float | None = None,
    natural_frequency_hz: float | None = None,
    columns: str | None = None,
    time_unit: str | None = None,
    channel: str | None = None,
    part_size: int = PART_SIZE,
    scheduler: str | None = None,
    workers: int | None = None,
    overwrite: bool = False,
    resume: bool = True,
    retries: int = 2,
    progress: Callable[[int, int], None] | None = None,
    before_part: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Predict every recording under ``recordings`` into the Parquet table ``out``.

    Parameters
    ----------
    recordings
        A campaign folder or its ``manifest.csv`` (:func:`campaign_inputs`), else a
        folder (searched recursively), a glob or a file; see :func:`find_recordings`.
    out
        The result table (one row per recording, see :func:`result_schema`).
    model_path
        The ONNX model (default: the predictor's, ``models/cnn.onnx``).
    fs_hz, natural_frequency_hz
        Sampling rate (needed for ``.npy``) and natural frequency (default: the
        manifest's, else each recording's sidecar; a recording without any fails with
        that reason), for every recording.
    columns, time_unit, channel
        How to read every recording (where a manifest leaves them empty), see
        :func:`stiffnet.recordings.read_recording`.
    part_size
        Recordings per task.
    scheduler, workers
        Where the parts run, see :func:`stiffnet.distributed.cluster.dask_client`.
    overwrite
        Replace an existing ``out``.
    resume
        Keep the finished parts of an interrupted run with the same inputs.
    retries
        Extra attempts of a part task that raised (Dask only; a bad recording does not
        raise, it gets an ``error``).
    progress
        ``progress(done, total)`` in parts.
    before_part
        Testing hook called in the task with the part index (fault injection).

    Returns
    -------
    dict
        A summary: counts per class, errors, parts kept and run, re-run parts.
    """
    check_target(scheduler, workers)
    out = _checked_output(out, overwrite, part_size)
    reading = (fs_hz, natural_frequency_hz, columns, time_unit, channel)
    paths, settings, manifest, fn_sources, fs_sources = _recordings_and_settings(
        recordings, reading
    )
    predictor = Predictor.load(model_path)  # fails early, here, on a bad model
    parts_dir = out.parent / f"{out.name}.parts"
    run = _fingerprint(tuple(paths), predictor.sha256, fs_hz, natural_frequency_hz,
                       (columns, time_unit, part_size))  # fmt: skip
    claim_parts_folder(parts_dir, run)  # a user's folder of that name is refused, not used
    t0 = time.perf_counter()
    # connect (or start the local cluster) before writing anything
    with dask_client(scheduler, workers) as client:
        jobs, records = _plan_parts(paths, settings, part_size, predictor, parts_dir, reading,
                                    resume, before_part, fn_sources=fn_sources,
                                    fs_sources=fs_sources)  # fmt: skip
        n_parts = len(records) + len(jobs)
        done = _run_parts(jobs, records, client, retries, progress, n_parts, 0)
        first = _parts_table(parts_dir, records, range(n_parts))
        dampings = None if manifest is None else _rig_dampings(manifest, paths)
        chain = None if manifest is None else _campaign_chain(first, paths, settings, predictor,
                                                              dampings)  # fmt: skip
        if chain is not None and chain["pooled"]:
            # the second round: every recording without its own sheet through the pooled chain
            # (with its contacts' dissipation free where the pool found it, as evaluate reads)
            again, flags = _campaign_settings(first, settings, chain["sensor"])
            hc = True if chain.get("contact_dissipation") else None
            jobs2, records2 = _plan_parts(paths, again, part_size, predictor, parts_dir,
                                          reading, resume, before_part, first_index=n_parts,
                                          campaign_chain=flags, fn_sources=fn_sources,
                                          fs_sources=fs_sources,
                                          penetration_dissipation=hc)  # fmt: skip
            records |= records2
            done = _add(done, _run_parts(jobs2, records, client, retries, progress,
                                         2 * n_parts, n_parts))  # fmt: skip
            second = _parts_table(parts_dir, records, range(n_parts, 2 * n_parts))
            chain = _confirmed(chain, first, second, flags)
            table = _campaign_table(first, second, flags) if chain["pooled"] else first
        else:
            table = first
    law = None
    if manifest is not None:
        table, law = _campaign_law(table)
    table = _joined_parts(parts_dir, table, predictor, out)
    unlisted = []
    if manifest is not None and Path(recordings).resolve() in (
        manifest.parent.resolve(),
        manifest.resolve(),
    ):  # the campaign folder itself (a glob picks some of its files on purpose)
        from stiffnet.campaign.manifest import unlisted_recordings

        listed = [Path(q).relative_to(manifest.parent).as_posix() for q in paths]
        unlisted = unlisted_recordings(manifest, listed)
    return {
        "out": str(out),
        "manifest": None if manifest is None else str(manifest),
        "unlisted": unlisted,
        **_table_summary(table, predictor),
        "sensor": chain,
        "campaign_law": law,
        "parts": len(records),
        "parts_kept": done["kept"],
        "rerun": done["rerun"],
        "backend": done["backend"],
        "seconds": round(time.perf_counter() - t0, 3),
    }


def _run_parts(
    jobs: list[PartJob],
    records: dict[int, dict[str, Any]],
    client: Any,
    retries: int,
    progress: Callable[[int, int], None] | None,
    total: int,
    before: int,
) -> dict[str, Any]:
    """Run `jobs` (parts not kept from an earlier run) and add their records to `records`;
    progress counts the `before` parts of earlier rounds and the kept ones as done."""
    kept = sum(1 for i in records if i >= before)
    if progress and kept:
        progress(before + kept, total)
    report = run_tasks(
        predict_part,
        jobs,
        client=client,
        retries=retries,
        names=[f"part-{j.index:05d}" for j in jobs],
        progress=(lambda d, _: progress(before + kept + d, total)) if progress else None,
    )
    report.raise_failures()
    for job, record in zip(jobs, report.results, strict=True):
        records[job.index] = record
    return {"kept": kept, "rerun": list(report.rerun), "backend": report.backend}


def _add(a: dict[str, Any], b: dict[str, Any]) -> dict[str, Any]:
    """Two rounds' counts as one."""
    return {"kept": a["kept"] + b["kept"], "rerun": a["rerun"] + b["rerun"],
            "backend": b["backend"]}  # fmt: skip


def _rig_dampings(manifest: Path, paths: list[str]) -> list[float | None]:
    """Each recording's ``damping_ratio`` from its manifest row (the rig's; None where not
    given), in the order of ``paths`` (a glob may name some of the campaign's files)."""
    from stiffnet.campaign.manifest import read_manifest

    by_path = {
        (manifest.parent / row.recording).resolve(): row.damping_ratio
        for row in read_manifest(manifest)
    }
    return [by_path.get(Path(p).resolve()) for p in paths]


def _campaign_chain(
    table: pa.Table,
    paths: list[str],
    settings: list[tuple],
    predictor: Predictor,
    dampings: list[float | None] | None = None,
) -> dict[str, Any]:
    """The campaign's pooled chain from the first round's identified chains
    (:func:`serving.campaign_chain.campaign_chain`); a recording read with a data sheet
    (the manifest's or its sidecar's) does not vote. Where too few identified one, the chain
    is fitted regardless of the gate here, recording by recording
    (:func:`serving.campaign_chain.identify_regardless`); the pooled chain's stages are
    profiled over the recordings read through it, the high-pass corner last from the free
    flight where the manifest's rows give the rig's damping (`dampings`;
    :func:`serving.campaign_chain.profiled_campaign_chain`)."""
    from stiffnet.recordings import read_recording

    sensors = [json.loads(s) if s else None for s in table.column("sensor").to_pylist()]
    read: dict[int, tuple | None] = {}  # each recording read once for both fits below

    def recording(i: int) -> tuple | None:
        if i not in read:
            fs, fn, columns, time_unit, channel, _ = settings[i]
            try:
                rec = read_recording(paths[i], fs_hz=fs, channel=channel, columns=columns,
                                     time_unit=time_unit)  # fmt: skip
                fn = record_natural_frequency(paths[i], None)[0] if fn is None else fn
                read[i] = (rec.accel, rec.fs_hz, fn)
            except StiffnetError:  # the first round already reported this recording's fault
                read[i] = None
        return read[i]

    def identify(i: int) -> dict | None:
        rec = recording(i)
        try:
            return None if rec is None else chain_fitted_regardless(*rec, predictor)
        except StiffnetError:
            return None

    sheets = [sheet for *_, sheet in settings]
    chain, sensors = identify_regardless(sensors, paths, sheets, identify)

    def through(i: int, sheet: dict, dissipation: bool = False) -> Any:  # read through sheet
        rec = recording(i)
        return None if rec is None else read_through(*rec, predictor, sheet, dissipation)

    contact_r2, free_damping = profile_readers(through)  # in this campaign's scope only
    # the same readings with the contact's dissipation growing with penetration fitted free:
    # the campaign is pooled as evaluate pools it
    dissipation = dissipation_readers(functools.partial(through, dissipation=True))

    def fns() -> list[float | None]:
        return [None if recording(i) is None else recording(i)[2] for i in range(len(paths))]

    return profiled_campaign_chain(chain, sensors, contact_r2, free_damping, fns,
                                   dampings or [None] * len(paths), sheets, dissipation,
                                   identify)  # fmt: skip


def _confirmed(
    chain: dict[str, Any], first: pa.Table, second: pa.Table, flags: tuple[bool, ...]
) -> dict[str, Any]:
    """The pooled chain kept where the recordings read through it (`flags`) lose little of
    their contact laws' R² (:func:`serving.campaign_chain.confirmed`)."""
    r2 = "restoring_force_contact_r2"
    pick = [i for i, f in enumerate(flags) if f]
    own = [{"contact_r2": first.column(r2)[i].as_py()} for i in pick]
    pooled = [{"contact_r2": second.column(r2)[i].as_py()} for i in pick]
    return confirmed(chain, own, pooled)


def _campaign_law(table: pa.Table) -> tuple[pa.Table, dict[str, Any]]:
    """The campaign's contact law judged on all its rows
    (:func:`stiffnet.uncertainty.campaign_law.campaign_law_decision`) and, where it is
    outside the model's world, every predicted row flagged with ``campaign_law``."""
    judged = [bool(j) for j in table.column("contact_law_judged").to_pylist()]
    fired = table.column("alarm_fired").to_pylist()
    # a row whose law was not read (its contact_law reading through a chain its map could
    # not undo, contact_law_judged) has no say in which checks fired either
    # a table resumed from parts written before the column holds no such reading
    unexplained = (
        table.column("contact_unexplained").to_pylist()
        if "contact_unexplained" in table.column_names
        else [False] * table.num_rows
    )
    seen = [
        [*law_checks_fired((f or "").split(",")), *([CONTACT_UNEXPLAINED] if u else [])]
        if j
        else []
        for f, j, u in zip(fired, judged, unexplained, strict=True)
    ]
    decision = campaign_law_decision(judged, [bool(s) for s in seen], seen=seen)
    if not decision["flag"]:
        return table, decision
    predicted = [e is None for e in table.column("error").to_pylist()]
    checks = [
        ",".join([*(f.split(",") if f else []), CAMPAIGN_LAW]) if p else f
        for f, p in zip(table.column("alarm_fired").to_pylist(), predicted, strict=True)
    ]
    flags = [p or o for o, p in zip(table.column("ood_flag").to_pylist(), predicted, strict=True)]
    for name, values, kind in (
        ("alarm_fired", checks, pa.string()),
        ("ood_flag", flags, pa.bool_()),
    ):
        table = table.set_column(table.schema.get_field_index(name), name, pa.array(values, kind))
    return table, decision


def _campaign_table(first: pa.Table, second: pa.Table, flags: tuple[bool, ...]) -> pa.Table:
    """The second round's rows, except where a recording's own contact law reads much worse
    through the pooled chain (:func:`serving.campaign_chain.reads_alone`): its first row."""
    r2 = "restoring_force_contact_r2"
    own, pooled = first.column(r2).to_pylist(), second.column(r2).to_pylist()
    pick = [i if f and not reads_alone({"contact_r2": a}, {"contact_r2": b}) else -1
            for i, (f, a, b) in enumerate(zip(flags, own, pooled, strict=True))]  # fmt: skip
    rows = [second.slice(i, 1) if i >= 0 else first.slice(j, 1) for j, i in enumerate(pick)]
    return pa.concat_tables(rows) if rows else second


def _campaign_settings(
    table: pa.Table, settings: list[tuple], sheet: dict[str, float]
) -> tuple[list[tuple], tuple[bool, ...]]:
    """The second round's settings: the pooled `sheet` on every recording read without a
    data sheet in the first (its own, the manifest's or the sidecar's, wins), and which."""
    sources = table.column("sensor_source").to_pylist()
    errors = table.column("error").to_pylist()
    flags = tuple(src != "data sheet" and err is None and s[-1] is None
                  for src, err, s in zip(sources, errors, settings, strict=True))  # fmt: skip
    return [(*s[:-1], sheet) if f else s for s, f in zip(settings, flags, strict=True)], flags


def _checked_output(out: str | Path, overwrite: bool, part_size: int) -> Path:
    """The result table's path, refused before any work: an existing file without
    `overwrite`, a folder, or parts of fewer than one recording."""
    if part_size < 1:
        raise StiffnetError(f"part size must be at least 1, got {part_size}")
    out = Path(out)
    if not out.is_dir() and out.suffix.lower() != ".parquet":
        # the table is Parquet whatever the name: 'results.csv' held Parquet bytes that a
        # spreadsheet or pandas.read_csv then reads as garbage
        raise StiffnetError(f"{out}: give a .parquet file name (the result table is Parquet)")
    if out.exists() and not overwrite:
        raise StiffnetError(f"{out} exists (use --overwrite to replace it)")
    if out.is_dir():
        raise StiffnetError(f"{out} is a folder: give a .parquet file name")
    return out


def _recordings_and_settings(
    recordings: str | Path, reading: tuple
) -> tuple[list[str], list[tuple], Path | None, list[str | None], list[str | None]]:
    """The recordings to predict, how to read each ``(fs, f_n, columns, time unit,
    channel, sensor data sheet)``, the manifest they came from and where each f_n and each
    given rate comes from: a campaign's manifest rows where there is one
    (:func:`campaign_inputs`), else every recording found, each read alike (its data sheet
    from its sidecar, if any)."""
    campaign = campaign_inputs(recordings, *reading)
    if campaign is not None:
        return campaign
    paths = [str(p) for p in find_recordings(recordings)]
    return paths, *listed_settings(paths, reading)


def listed_settings(
    paths: list[str], reading: tuple
) -> tuple[list[tuple[Any, ...]], Path | None, list[str | None], list[str | None]]:
    """How to read recordings found by a glob or a folder that is not a campaign, the one
    manifest listing them all (None: none does), where each f_n comes from and where each
    rate given by a row does (:func:`fs_source`): a recording
    listed by the manifest of the campaign it sits in is read with its row, as the campaign
    folder would read it (that manifest read once, its sidecar agreement checked); the
    others alike, with the options (``reading``). Files of one campaign are then judged as
    that campaign (its sensor chain pooled, its contact law counted over them).

    Raises
    ------
    StiffnetError
        A campaign manifest above a recording does not read (its problems, naming it).
    """
    from stiffnet.campaign.manifest import campaign_manifest_above, read_manifest

    rows_of: dict[Path, dict[Path, Any]] = {}
    settings, sources, rate_sources, n_listed = [], [], [], 0
    for path in paths:
        manifest = campaign_manifest_above(path)
        row = None
        if manifest is not None:
            if manifest not in rows_of:
                rows_of[manifest] = {
                    (manifest.parent / r.recording).resolve(): r for r in read_manifest(manifest)
                }
            row = rows_of[manifest].get(Path(path).resolve())
        if row is None:
            settings.append((*reading, None))
            sources.append(fn_source(reading[1]))
            rate_sources.append(None)
            continue
        n_listed += 1
        settings.append(row_settings(row, *reading))
        sources.append(row.natural_frequency_source(manifest) or fn_source(reading[1]))
        rate_sources.append(fs_source(row, manifest))
    one = next(iter(rows_of)) if len(rows_of) == 1 and n_listed == len(paths) else None
    return settings, one, sources, rate_sources


def _plan_parts(
    paths: list[str],
    settings: list[tuple],
    part_size: int,
    predictor: Predictor,
    parts_dir: Path,
    reading: tuple,
    resume: bool,
    before_part: Callable[[int], None] | None,
    first_index: int = 0,
    campaign_chain: tuple[bool, ...] | None = None,
    fn_sources: list[str | None] | None = None,
    fs_sources: list[str | None] | None = None,
    penetration_dissipation: bool | None = None,
) -> tuple[list[PartJob], dict[int, dict[str, Any]]]:
    """The parts still to run (jobs) and the records of those an interrupted run with the
    same inputs finished (kept when `resume`), by part index (from `first_index`: a second
    round's parts follow the first's; `penetration_dissipation`: :attr:`PartJob`'s, in the
    parts' fingerprint where set)."""
    fs_hz, natural_frequency_hz, columns, time_unit, _ = reading
    model_file = str(Path(predictor.model.path).resolve())
    jobs, records = [], {}
    for index, lo in enumerate(range(0, len(paths), part_size), start=first_index):
        chunk = tuple(paths[lo : lo + part_size])
        chunk_settings = tuple(settings[lo : lo + part_size])
        flags = None if campaign_chain is None else tuple(campaign_chain[lo : lo + part_size])
        fn_from = None if fn_sources is None else tuple(fn_sources[lo : lo + part_size])
        fs_from = None if fs_sources is None else tuple(fs_sources[lo : lo + part_size])
        layout = (columns, time_unit, *(["dissipation"] if penetration_dissipation else []))
        fp = _fingerprint(chunk, predictor.sha256, fs_hz, natural_frequency_hz, layout,
                          chunk_settings)  # fmt: skip
        record = _finished_part(parts_dir, index, fp) if resume else None
        if record is not None:
            records[index] = record
            continue
        files = tuple(str(Path(p).resolve()) for p in chunk)
        jobs.append(PartJob(index, chunk, files, str(parts_dir.resolve()), model_file,
                            predictor.sha256, tuple(predictor.class_names), fs_hz,
                            natural_frequency_hz, fp, columns, time_unit,
                            settings=chunk_settings, campaign_chain=flags,
                            fn_sources=fn_from, fs_sources=fs_from,
                            penetration_dissipation=penetration_dissipation,
                            before=before_part))  # fmt: skip
    return jobs, records


def _parts_table(parts_dir: Path, records: dict[int, dict[str, Any]], indices: range) -> pa.Table:
    """The parts `indices` concatenated in order."""
    return pa.concat_tables(pq.read_table(parts_dir / records[i]["file"]) for i in indices)


def _joined_parts(parts_dir: Path, table: pa.Table, predictor: Predictor, out: Path) -> pa.Table:
    """The joined parts' `table` written to `out` (atomically) with the model in the schema
    metadata; the run's own part files are then removed."""
    table = table.replace_schema_metadata(
        {"stiffnet.model": predictor.name, "stiffnet.model_sha256": predictor.sha256}
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(out, _parquet_bytes(table))
    remove_parts_folder(parts_dir)  # only the run's own files
    return table


def _table_summary(table: pa.Table, predictor: Predictor) -> dict[str, Any]:
    """Rows, failures (path and reason), counts per class and the model of a result table."""
    classes = table.column("class").drop_null().to_pylist()
    errors = table.select(["path", "error"]).to_pylist()
    return {
        "recordings": table.num_rows,
        "failed": [r for r in errors if r["error"] is not None],
        "errors": int(table.column("error").is_valid().to_numpy(zero_copy_only=False).sum()),
        "class_counts": {name: classes.count(name) for name in predictor.class_names},
        "model": {"name": predictor.name, "sha256": predictor.sha256},
    }
