"""Dataset folders: Parquet shards plus a data card that marks completeness."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from stiffnet.errors import StiffnetError
from stiffnet.io_utils import sha256_file, write_json_atomic

CARD = "card.json"


def write_shard(folder: Path, index: int, table: pa.Table) -> dict[str, Any]:
    """Write one shard atomically; returns its entry for the card."""
    shards = folder / "shards"
    shards.mkdir(exist_ok=True)
    name = f"shard-{index:05d}.parquet"
    tmp = shards / f".{name}.tmp"
    pq.write_table(table, tmp, compression="zstd")
    tmp.replace(shards / name)
    return {"file": f"shards/{name}", "rows": table.num_rows, "sha256": sha256_file(shards / name)}


def write_card(folder: Path, card: dict[str, Any]) -> None:
    """The card is written last: a folder without it is not a finished dataset."""
    write_json_atomic(folder / CARD, card)


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


def load_dataset(folder: str | Path, verify: bool = False) -> Dataset:
    """Load a finished dataset; ``verify`` checks each shard's SHA-256 against the card."""
    folder = Path(folder)
    card_path = folder / CARD
    if not card_path.is_file():
        raise StiffnetError(f"{folder} is not a finished stiffnet dataset (no {CARD})")
    card = json.loads(card_path.read_text())
    tables = []
    for entry in card["shards"]:
        path = folder / entry["file"]
        if not path.is_file():
            raise StiffnetError(f"dataset {folder}: shard {entry['file']} is missing")
        if verify and sha256_file(path) != entry["sha256"]:
            raise StiffnetError(f"dataset {folder}: shard {entry['file']} is corrupt (SHA-256)")
        tables.append(pq.read_table(path))
    return Dataset(pa.concat_tables(tables), card)
