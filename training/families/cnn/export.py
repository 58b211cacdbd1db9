"""Export the 1-D CNN as one self-contained ONNX file plus a model card.

The file has one input ``windows`` (float32, ``[N, C, L]``, dynamic batch ``N``:
the output of :func:`stiffnet.features.windows.window_tensor`) and four
outputs: ``probabilities`` (float32, ``[N, n_classes]``, softmax, columns in
the order of metadata ``class_names``), ``log_beta`` (float32, ``[N, 1]``),
``log_beta_scale`` (``[N, 1]``, log of the expected size of the log-beta error
of the window) and ``embedding`` (``[N, width]``, the pooled features the heads
read; the alarm compares them with the training data's).
It is written by ``torch.onnx.export`` (the dynamo exporter, ``dynamic_shapes``
for the batch axis; the legacy TorchScript exporter with ``dynamic_axes`` if
that fails) with ``external_data=False``: the weights are inside the file.

``metadata_props`` (all strings, JSON-encoded unless strings): ``model_kind``
(``"stiffnet.cnn"``), ``class_names``, ``class_indices``, ``input_name``,
``canonical_rate`` (samples per natural period), ``window_periods``,
``window_length``, ``delays`` (canonical samples), ``delay_fraction``,
``normalisation``, ``window_version``, ``beta_transform`` (``"log"``),
``requires_natural_frequency`` (always true), ``opset`` and what the caller
adds (``training_data_sha256``, ``conformal_quantile``, ...). Writes are atomic.
"""

from __future__ import annotations

import contextlib
import logging
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import onnx
import torch

from serving.families.cnn import CNNFamily
from stiffnet.features.windows import NORMALISATION, WINDOW_VERSION, preprocessing_contract
from training.families.cnn.network import ProbabilityModel, StiffnessCNN
from training.onnx_export import onnx_session, write_model

#: ai.onnx opset of the exported graph.
TARGET_OPSET = 18
INPUT_NAME = CNNFamily.input_name
OUTPUT_NAMES = ["probabilities", "log_beta", "log_beta_scale", "embedding"]


@contextlib.contextmanager
def _quiet_exporter_logs() -> Iterator[None]:
    """Silence torch.onnx's exporter loggers (e.g. four "torchvision is not installed.
    Skipping torchvision::nms" warnings: stiffnet has no torchvision ops)."""
    loggers = [logging.getLogger(n) for n in ("torch.onnx", "torch._dynamo", "torch.export")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.ERROR)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


def _export_proto(net: StiffnessCNN, n_channels: int, length: int) -> onnx.ModelProto:
    wrapper = ProbabilityModel(net).eval()
    example = torch.zeros(2, n_channels, length)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.onnx"
        with warnings.catch_warnings(), _quiet_exporter_logs():
            warnings.simplefilter("ignore")
            common = dict(input_names=[INPUT_NAME], output_names=OUTPUT_NAMES,
                          opset_version=TARGET_OPSET)  # fmt: skip
            try:
                torch.onnx.export(
                    wrapper, (example,), str(path), **common, dynamo=True,
                    dynamic_shapes={"windows": {0: torch.export.Dim("N")}},
                    external_data=False, verbose=False,
                )  # fmt: skip
            except Exception:  # noqa: BLE001 - fall back to the TorchScript exporter
                torch.onnx.export(
                    wrapper, (example,), str(path), **common, dynamo=False,
                    dynamic_axes={INPUT_NAME: {0: "N"}, **{o: {0: "N"} for o in OUTPUT_NAMES}},
                )  # fmt: skip
        model = onnx.load(str(path), load_external_data=True)
    for vi in [*model.graph.input, *model.graph.output]:  # name the dynamic batch axis
        dims = vi.type.tensor_type.shape.dim
        if dims:
            dims[0].ClearField("dim_value")
            dims[0].dim_param = "N"
    onnx.checker.check_model(model)
    return model


def export_cnn_onnx(
    net: StiffnessCNN,
    class_names: list[str],
    path: str | Path,
    *,
    rate: int,
    periods: int,
    delays: list[int],
    delay_fraction: float,
    metadata: dict[str, Any],
    card: dict[str, Any],
) -> dict[str, Any]:
    """Write the ONNX model and its card (``<stem>.card.json``) atomically.

    Parameters
    ----------
    net : StiffnessCNN
        Fitted network (put in eval mode).
    class_names : list of str
        Name of each class index (the probability columns, in order).
    path : str or Path
        Destination ``.onnx`` file.
    rate, periods : int
        Canonical samples per natural period and natural periods per window.
    delays : list of int
        Channel delays in canonical samples.
    delay_fraction : float
        The delay rule in natural periods.
    metadata : dict
        Extra ``metadata_props``; should include ``training_data_sha256`` and
        ``conformal_quantile``.
    card : dict
        Model card content; the file's SHA-256, the metadata, the opset and
        the input/output shapes are added.

    Returns
    -------
    dict
        The model card as written.
    """
    path = Path(path)
    net.eval()
    length = rate * periods
    model = _export_proto(net, len(delays), length)
    props = {
        "model_kind": CNNFamily.model_kind,
        "class_names": list(class_names),
        "class_indices": list(range(len(class_names))),
        "input_name": INPUT_NAME,
        "canonical_rate": rate,
        "window_periods": periods,
        "window_length": length,
        "delays": list(delays),
        "delay_fraction": delay_fraction,
        "normalisation": NORMALISATION,
        "window_version": WINDOW_VERSION,
        "hop_periods": periods,
        "preprocessing": preprocessing_contract(rate, periods, delays),
        "beta_transform": "log",
        "requires_natural_frequency": True,
        "opset": TARGET_OPSET,
        **metadata,
    }
    shapes = {
        "inputs": {INPUT_NAME: ["N", len(delays), length]},
        "outputs": {
            "probabilities": ["N", len(class_names)],
            "log_beta": ["N", 1],
            "log_beta_scale": ["N", 1],
            "embedding": ["N", int(net.cls.in_features)],
        },
    }
    return write_model(model, path, props, shapes, card)


def onnx_predict_cnn(path: str | Path, X: np.ndarray) -> dict[str, np.ndarray]:
    """Run the exported model: ``probabilities``, ``log_beta`` (N,) and ``beta``."""
    sess = onnx_session(path)
    outs = sess.run(None, {INPUT_NAME: np.asarray(X, dtype=np.float32)})
    got = dict(zip([o.name for o in sess.get_outputs()], outs, strict=True))
    out = {k: v[:, 0] if k in ("log_beta", "log_beta_scale") else v for k, v in got.items()}
    out["beta"] = np.exp(out["log_beta"])
    return out


def parity_cnn(path: str | Path, net: StiffnessCNN, X: np.ndarray) -> dict[str, float]:
    """Largest ONNX-vs-torch differences on `X`.

    Returns
    -------
    dict
        ``max_abs_proba_diff``, ``max_abs_log_beta_diff`` and ``label_agreement``.
    """
    from training.families.cnn.network import predict_cnn

    if len(X) == 0:
        return {"max_abs_proba_diff": 0.0, "max_abs_log_beta_diff": 0.0, "label_agreement": 1.0}
    out = onnx_predict_cnn(path, X)
    p, lb = predict_cnn(net, np.asarray(X, dtype=np.float32))
    return {
        "max_abs_proba_diff": float(np.max(np.abs(out["probabilities"] - p))),
        "max_abs_log_beta_diff": float(np.max(np.abs(out["log_beta"] - lb))),
        "label_agreement": float(np.mean(out["probabilities"].argmax(axis=1) == p.argmax(axis=1))),
    }
