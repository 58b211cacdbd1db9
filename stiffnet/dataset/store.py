"""Dataset folders: Parquet shards, per-shard records, and a data card that marks completeness.

Layout of ``data/NAME/``::

    job.json                     what is being built (config fingerprint); written first
    shards/shard-NNNNN.parquet   one row per window, written atomically by its task
    records/shard-NNNNN.json     the shard's record (rows, SHA-256, class counts), after it
    card.json                    the data card, written last: only then is the folder a dataset

A folder without ``card.json`` is an unfinished run: loaders refuse it, and
``generate_dataset`` resumes it, keeping every shard whose record matches its file.
``shards/`` holds nothing but the Parquet files (temporary files start with a dot), so
Dask, pyarrow, pandas, DuckDB or Spark read ``shards/`` directly as one dataset.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from stiffnet.errors import StiffnetError
from stiffnet.inputs import read_json
from stiffnet.io_utils import sha256_file, write_bytes_atomic, write_json_atomic

CARD = "card.json"
JOB = "job.json"
SHARDS = "shards"
RECORDS = "records"


def shard_name(index: int) -> str:
    return f"shard-{index:05d}"


def write_shard(folder: Path, index: int, table: pa.Table) -> dict[str, Any]:
    """Write one shard atomically (unique temporary name, then rename); returns its entry.

    Two attempts of the same shard (a worker presumed lost still running) never write
    to the same temporary file, and the shard is the same bytes whichever wins.
    """
    shards = Path(folder) / SHARDS
    shards.mkdir(parents=True, exist_ok=True)
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    path = shards / f"{shard_name(index)}.parquet"
    write_bytes_atomic(path, sink.getvalue().to_pybytes())
    return {"file": f"{SHARDS}/{path.name}", "rows": table.num_rows, "sha256": sha256_file(path)}


def write_shard_record(folder: Path, index: int, record: dict[str, Any]) -> None:
    """Record a finished shard (after its Parquet file is in place)."""
    records = Path(folder) / RECORDS
    records.mkdir(parents=True, exist_ok=True)
    write_json_atomic(records / f"{shard_name(index)}.json", record)


def finished_shard(folder: Path, index: int, fingerprint: str) -> dict[str, Any] | None:
    """The record of shard ``index`` if the shard is finished and intact, else ``None``.

    Finished means: a record of the same job (``fingerprint``) exists, and the Parquet
    file it names is there with the recorded SHA-256.
    """
    path = Path(folder) / RECORDS / f"{shard_name(index)}.json"
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("fingerprint") != fingerprint:
        return None
    shard = Path(folder) / str(record.get("file", ""))
    if not shard.is_file() or sha256_file(shard) != record.get("sha256"):
        return None
    return record


def write_card(folder: Path, card: dict[str, Any]) -> None:
    """The card is written last: a folder without it is not a finished dataset."""
    write_json_atomic(Path(folder) / CARD, card)


@dataclass
class Dataset:
    """A loaded dataset: the table of windows and its data card."""

    table: pa.Table
    card: dict[str, Any]

    def __len__(self) -> int:
        return self.table.num_rows

    @property
    def class_names(self) -> list[str]:
        return list(self.card["class_names"])

    def windows(self) -> list[np.ndarray]:
        """The acceleration windows (float32, lengths vary with the sampling rate)."""
        col = self.table.column("accel").combine_chunks()
        flat = col.values.to_numpy()
        offsets = col.offsets.to_numpy()
        return [flat[offsets[i] : offsets[i + 1]] for i in range(len(col))]

    def column(self, name: str) -> np.ndarray:
        return self.table.column(name).to_numpy()


def load_dataset(folder: str | Path, verify: bool = True) -> Dataset:
    """Load a finished dataset, checking each shard's SHA-256 against the card.

    ``verify=False`` skips the hashes (a caller that has just checked them).
    """
    folder = Path(folder)
    card_path = folder / CARD
    if not card_path.is_file():
        hint = " - an interrupted run; rerun `stiffnet simulate` to resume it" if (
            folder / JOB).is_file() else ""  # fmt: skip
        raise StiffnetError(f"{folder} is not a finished stiffnet dataset (no {CARD}){hint}")
    card = read_json(card_path, "data card")
    shards = card.get("shards") if isinstance(card, dict) else None
    if not isinstance(shards, list) or not all(
        isinstance(e, dict) and isinstance(e.get("file"), str) and isinstance(e.get("sha256"), str)
        for e in shards
    ):
        raise StiffnetError(f"{card_path}: not a stiffnet data card (no list of shards)")
    root = folder.resolve()
    tables = []
    for entry in shards:
        path = folder / entry["file"]
        if not path.resolve().is_relative_to(root):
            raise StiffnetError(f"dataset {folder}: shard {entry['file']} lies outside the folder")
        if not path.is_file():
            raise StiffnetError(f"dataset {folder}: shard {entry['file']} is missing")
        # the card is the dataset's identity: a shard written by another run (a mixed
        # folder) or changed since is refused
        data = path.read_bytes()  # hashed and parsed from the same bytes
        if verify and hashlib.sha256(data).hexdigest() != entry["sha256"]:
            raise StiffnetError(
                f"dataset {folder}: shard {entry['file']} does not match its SHA-256 in "
                f"{CARD} (corrupt, or written by another run)"
            )
        tables.append(pq.read_table(pa.BufferReader(data)))
    return Dataset(pa.concat_tables(tables), card)
