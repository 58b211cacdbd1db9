"""A training run's dataset: loading it, its identity and the summary a model card keeps."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from stiffnet.dataset.store import CARD, load_dataset
from stiffnet.io_utils import sha256_file


def load_training_data(data_dir: Path, say: Callable[[str], None]) -> tuple[Any, list[str], str]:
    """The dataset, its class names and the SHA-256 of its card (the data's identity)."""
    ds = load_dataset(data_dir)
    say(f"dataset {data_dir}: {len(ds)} windows, {ds.card.get('n_trajectories')} trajectories")
    return ds, ds.class_names, sha256_file(data_dir / CARD)


def alarm_info(ds: Any, card_sha: str) -> dict[str, Any]:
    """Provenance of the alarm, and the class edges its class-edge check needs."""
    classes = (ds.card.get("config") or {}).get("classes") or []
    edges = [c["beta"][0] for c in classes] + ([classes[-1]["beta"][1]] if classes else [])
    return {"training_data_sha256": card_sha, "class_edges": edges}


def data_summary(data_dir: Path, card_sha: str, ds: Any) -> dict[str, Any]:
    """What the model card says about its training data."""
    keys = ("n_trajectories", "seed", "class_balance", "code_version")
    sweep = (ds.card.get("config") or {}).get("sweep") or {}
    return {
        "path": str(data_dir),
        "card_sha256": card_sha,
        "n_windows": len(ds),
        **{k: ds.card.get(k) for k in keys},
        # the rig's f_n in the training data: the predictor's default when a recording
        # comes without one (a number, or the [lo, hi] range it was drawn from)
        "natural_frequency_hz": sweep.get("natural_frequency_hz"),
        # the world the model was trained in: the sweep and each effect's priors
        "priors": {
            "sweep": sweep,
            "effects": (ds.card.get("config") or {}).get("effects") or [],
        },
    }
