"""Loading a shipped ONNX model: integrity check against its card, metadata, session.

A model is a file ``NAME.onnx`` and its card ``NAME.card.json`` (written by its
family's exporter, ``training/families/NAME/``). Loading

1. reads the card (plain JSON) and refuses the model when the file's SHA-256
   differs from the card's ``sha256`` - a model is never run unverified;
2. opens an ONNX Runtime session (CPU, ``intra_op_num_threads`` = `threads`,
   ``inter_op_num_threads`` = 1), refusing a file ONNX Runtime cannot parse;
3. reads the metadata from the file's ``metadata_props`` (JSON-decoded; the
   card's copy fills anything missing) and checks it describes a model of a
   family the predictor serves (:func:`serving.families.family_for`), with the
   family's one input and the outputs ``probabilities`` and ``log_beta``.

Nothing is unpickled: the card and the reference files are JSON and the model is
an ONNX protobuf run by ONNX Runtime.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stiffnet.errors import StiffnetError
from stiffnet.inputs import MAX_DEPTH, MAX_DOCUMENT_BYTES, read_json
from stiffnet.io_utils import sha256_file
from stiffnet.shipped import shipped_file

if TYPE_CHECKING:
    from serving.families.base import ModelFamily


def default_model_path() -> Path:
    """The shipped model of the default family (:attr:`ModelFamily.default`):
    ``models/KIND.onnx`` of the repository, else of the current folder."""
    from serving.families import families

    (kind,) = {f.kind for f in families().values() if f.default}
    return shipped_file(f"{kind}.onnx")


def card_path(model_path: Path) -> Path:
    """``NAME.card.json`` beside ``NAME.onnx``."""
    return model_path.with_suffix(".card.json")


#: Metadata values the exporters store as plain strings. Decoding them as JSON would turn
#: a hash made only of digits into a number, so they are never decoded.
STRING_KEYS = frozenset(
    {
        "model_kind",
        "input_name",
        "normalisation",
        "beta_transform",
        "training_data_sha256",
        "alarm_reference",
        "alarm_sha256",
        "interval",
    }
)


def onnx_metadata(sess: Any, where: object = "model") -> dict[str, Any]:
    """An ONNX Runtime session's custom metadata, JSON values decoded (see :data:`STRING_KEYS`).

    Bounded like every document stiffnet reads (:mod:`stiffnet.inputs`): at most
    :data:`~stiffnet.inputs.MAX_DOCUMENT_BYTES` in all and no value nested deeper
    than :data:`~stiffnet.inputs.MAX_DEPTH` levels, else a one-line
    :class:`StiffnetError` naming the model and the key - in the library, so the
    CLI, HTTP and Python users all get it.
    """
    items = sess.get_modelmeta().custom_metadata_map.items()
    size = sum(len(k) + len(v) for k, v in items)
    if size > MAX_DOCUMENT_BYTES:
        raise StiffnetError(
            f"{where}: the model's metadata is larger than {MAX_DOCUMENT_BYTES // 2**20} MB"
        )
    return {k: decode_metadata_value(k, v, where) for k, v in items}


def decode_metadata_value(key: str, value: str, where: object = "model") -> Any:
    """One metadata value: JSON-decoded, except the plain strings of :data:`STRING_KEYS`.

    Raises
    ------
    StiffnetError
        The value is JSON nested deeper than :data:`~stiffnet.inputs.MAX_DEPTH` levels.
    """
    if key in STRING_KEYS:
        return value
    what = f"{where}: metadata {key!r}"
    if value.count("[") + value.count("{") > MAX_DEPTH:
        check_nesting(value, what)  # before the (recursive) decoder sees it
    try:
        return json.loads(value)
    except ValueError:
        return value  # other plain string values are stored unencoded too


def check_nesting(text: str, what: str) -> None:
    """Refuse JSON text whose brackets open deeper than :data:`~stiffnet.inputs.MAX_DEPTH`
    (brackets inside strings count too: conservative, and no decoding needed)."""
    depth = 0
    for ch in text:
        if ch in "[{":
            depth += 1
            if depth > MAX_DEPTH:
                raise StiffnetError(f"{what} is nested deeper than {MAX_DEPTH} levels")
        elif ch in "]}":
            depth -= 1


@dataclass
class LoadedModel:
    """A verified ONNX model ready to run.

    Attributes
    ----------
    path : Path
        The ``.onnx`` file.
    name : str
        File stem.
    kind : str
        The model's family (:attr:`serving.families.base.ModelFamily.kind`).
    sha256 : str
        SHA-256 of the file (equal to the card's).
    metadata : dict
        Decoded ``metadata_props`` (class names, window geometry, conformal quantile...).
    card : dict
        The model card.
    session : onnxruntime.InferenceSession
        The session (thread-safe for concurrent ``run`` calls).
    input_name : str
        Name of the model's input.
    family : serving.families.ModelFamily
        What the model reads from a recording's windows.
    """

    path: Path
    name: str
    kind: str
    sha256: str
    metadata: dict[str, Any]
    card: dict[str, Any]
    session: Any = field(repr=False)
    input_name: str = ""
    family: ModelFamily | None = field(default=None, repr=False)

    @property
    def class_names(self) -> list[str]:
        return [str(c) for c in self.metadata["class_names"]]

    @property
    def output_names(self) -> list[str]:
        return [o.name for o in self.session.get_outputs()]

    @property
    def conformal_quantile(self) -> float | None:
        q = self.metadata.get("conformal_quantile")
        return float(q) if q is not None else None


def load_model(path: str | Path | None = None, threads: int = 1) -> LoadedModel:
    """Verify and open a model (see the module notes).

    Parameters
    ----------
    path : str or Path, optional
        The ``.onnx`` file; default :func:`default_model_path`.
    threads : int, optional
        ONNX Runtime intra-op threads (>= 1).

    Returns
    -------
    LoadedModel

    Raises
    ------
    StiffnetError
        Missing file or card, SHA-256 mismatch, a file ONNX Runtime cannot
        load, or metadata that is no served family's.
    """
    import onnxruntime as ort

    from serving.families import families, family_for

    p = Path(path) if path is not None else default_model_path()
    if int(threads) < 1:
        raise StiffnetError(f"threads must be >= 1, got {threads}")
    if not p.is_file():
        raise StiffnetError(f"{p}: model file not found")
    cp = card_path(p)
    if not cp.exists():
        raise StiffnetError(f"{p}: model card {cp.name} not found (needed to verify the model)")
    card = read_json(cp, "model card")  # bounded, finite, depth-checked (stiffnet.inputs)
    if not isinstance(card, dict) or not isinstance(card.get("sha256"), str):
        raise StiffnetError(f"{cp}: model card has no sha256")
    digest = sha256_file(p)
    if digest != card["sha256"].lower():
        raise StiffnetError(
            f"{p}: SHA-256 {digest[:12]}... does not match its card ({card['sha256'][:12]}...); "
            "refusing to load a modified model"
        )
    so = ort.SessionOptions()
    so.intra_op_num_threads = int(threads)
    so.inter_op_num_threads = 1
    so.log_severity_level = 3  # errors only: warnings would clutter the CLI
    try:
        sess = ort.InferenceSession(str(p), so, providers=["CPUExecutionProvider"])
    except Exception as exc:  # noqa: BLE001 - ORT raises assorted types on bad files
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise StiffnetError(f"{p}: not a loadable ONNX model ({first[:200]})") from None
    meta = dict(card.get("metadata") or {})
    meta.update(onnx_metadata(sess, p))
    family = family_for(meta.get("model_kind"))
    if family is None:
        served = " or ".join(f.kind for f in families().values())
        raise StiffnetError(
            f"{p}: model_kind {meta.get('model_kind')!r} is not a stiffnet {served} model"
        )
    input_name = family.input_name
    inputs = [i.name for i in sess.get_inputs()]
    outputs = {o.name for o in sess.get_outputs()}
    if inputs != [input_name] or not {"probabilities", "log_beta"} <= outputs:
        raise StiffnetError(
            f"{p}: expected input {input_name!r} and outputs probabilities, log_beta; "
            f"got inputs {inputs} and outputs {sorted(outputs)}"
        )
    if not isinstance(meta.get("class_names"), list) or not meta["class_names"]:
        raise StiffnetError(f"{p}: metadata has no class_names")
    family.check_metadata(meta, p)
    return LoadedModel(p, p.stem, family.kind, digest, meta, card, sess, input_name, family(meta))
