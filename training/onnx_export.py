"""What every family's ONNX export shares: metadata, the atomic write, the card, a session.

A family builds its graph (skl2onnx, torch.onnx, ...) and calls
:func:`write_model`, which stores the metadata in ``metadata_props`` (strings;
JSON-encoded unless already strings), writes ``NAME.onnx`` atomically and then its
card ``NAME.card.json`` (file name, SHA-256, opsets, input/output shapes, the
metadata, then the caller's entries).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import onnx
from onnx import helper

from stiffnet.io_utils import sha256_file, write_bytes_atomic, write_json_atomic


def write_model(
    model: onnx.ModelProto,
    path: str | Path,
    props: dict[str, Any],
    shapes: dict[str, dict[str, list[Any]]],
    card: dict[str, Any],
) -> dict[str, Any]:
    """Write `model` with metadata `props` to `path` and its card beside it.

    Parameters
    ----------
    model : onnx.ModelProto
        The checked graph.
    path : str or Path
        Destination ``.onnx`` file (its folder is created).
    props : dict
        The metadata (``model_kind``, ``class_names``, ...).
    shapes : dict
        ``{"inputs": {name: shape}, "outputs": {name: shape}}`` for the card.
    card : dict
        The rest of the model card (config, data, metrics, ...).

    Returns
    -------
    dict
        The model card as written.
    """
    path = Path(path)
    meta = {k: v if isinstance(v, str) else json.dumps(v) for k, v in props.items()}
    helper.set_model_props(model, meta)
    model.producer_name = "stiffnet"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, model.SerializeToString())
    full = {
        "model_file": path.name,
        "sha256": sha256_file(path),
        "opset": {o.domain or "ai.onnx": o.version for o in model.opset_import},
        **shapes,
        "metadata": props,
        **card,
    }
    write_json_atomic(path.with_suffix(".card.json"), full)
    return full


def rewrite_metadata(
    path: str | Path, update: dict[str, Any], card_update: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Add or replace metadata of an exported model, its graph untouched; the card follows.

    The model file is rewritten atomically, then its card with the new SHA-256, the
    merged metadata and `card_update`. Returns the card as written.
    """
    path = Path(path)
    card_path = path.with_suffix(".card.json")
    card = json.loads(card_path.read_text())
    model = onnx.load(str(path))
    props = {p.key: p.value for p in model.metadata_props}
    props.update({k: v if isinstance(v, str) else json.dumps(v) for k, v in update.items()})
    del model.metadata_props[:]
    helper.set_model_props(model, props)
    write_bytes_atomic(path, model.SerializeToString())
    card.update(
        sha256=sha256_file(path),
        metadata={**(card.get("metadata") or {}), **update},
        **(card_update or {}),
    )
    write_json_atomic(card_path, card)
    return card


def onnx_session(path: str | Path) -> Any:
    """onnxruntime session with one intra-op thread (deterministic, no oversubscription)."""
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.inter_op_num_threads = 1
    return ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])
