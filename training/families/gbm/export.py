"""Export the two gradient-boosting models as one ONNX file plus a model card.

The file has one input ``features`` (float32, shape ``[N, k]``, dynamic batch)
and three outputs: ``label`` (int64 class index), ``probabilities`` (float32,
``[N, n_classes]``, columns in the order of metadata ``class_names``) and
``log_beta`` (float32, ``[N, 1]``). The classifier and the regressor are
converted separately by skl2onnx (``zipmap=False``) and their graphs merged,
the regressor's names prefixed with ``beta_``.

``metadata_props`` (all strings): ``model_kind``, ``class_names`` and
``feature_names`` (JSON lists), ``feature_version``, ``training_data_sha256``
(SHA-256 of the dataset's ``card.json``), ``conformal_quantile`` (half-width
in log-beta), ``conformal_coverage``, ``beta_transform`` (``"log"``),
``opset``, ``requires_natural_frequency``.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import onnx
from onnx import compose, helper
from skl2onnx import convert_sklearn
from skl2onnx.common.data_types import FloatTensorType

from serving.families.gbm import GBMFamily
from training.onnx_export import onnx_session, write_model

#: ai.onnx opset of the exported graph.
TARGET_OPSET = 17
INPUT_NAME = GBMFamily.input_name


def _convert(model: Any, n_features: int, options: dict | None = None) -> onnx.ModelProto:
    with warnings.catch_warnings():
        # skl2onnx 1.20 passes bools to int attributes; protobuf 6.33 only warns about it
        warnings.filterwarnings("ignore", "Field onnx.AttributeProto.ints", DeprecationWarning)
        return convert_sklearn(
            model,
            initial_types=[(INPUT_NAME, FloatTensorType([None, n_features]))],
            target_opset={"": TARGET_OPSET, "ai.onnx.ml": 3},
            options=options,
        )


def build_onnx(classifier: Any, regressor: Any, n_features: int) -> onnx.ModelProto:
    """Merge the converted classifier and regressor into one graph.

    Parameters
    ----------
    classifier : HistGradientBoostingClassifier
        Fitted classifier.
    regressor : HistGradientBoostingRegressor
        Fitted regressor on ``log(beta)``.
    n_features : int
        Width of the feature vector.

    Returns
    -------
    onnx.ModelProto
        Checked model with outputs ``label``, ``probabilities`` and ``log_beta``.
    """
    clf = _convert(classifier, n_features, {id(classifier): {"zipmap": False}})
    reg = compose.add_prefix(_convert(regressor, n_features), "beta_")
    g = clf.graph
    names = {o.name: o for o in g.output}
    renames = {"label": "label", "probabilities": "probabilities"}
    assert set(renames) <= set(names), f"unexpected classifier outputs {list(names)}"
    prefixed_in = "beta_" + INPUT_NAME
    for node in reg.graph.node:
        node.input[:] = [INPUT_NAME if i == prefixed_in else i for i in node.input]
    (reg_out,) = reg.graph.output
    g.node.extend(reg.graph.node)
    g.node.append(helper.make_node("Identity", [reg_out.name], ["log_beta"], name="log_beta_out"))
    g.initializer.extend(reg.graph.initializer)
    g.output.append(helper.make_tensor_value_info("log_beta", onnx.TensorProto.FLOAT, [None, 1]))
    g.name = "stiffnet_gbm"
    for vi in [*g.input, *g.output]:  # name the dynamic batch axis
        dims = vi.type.tensor_type.shape.dim
        if dims:
            dims[0].dim_param = "N"
    ops = {o.domain: o.version for o in clf.opset_import}
    for o in reg.opset_import:
        ops[o.domain] = max(ops.get(o.domain, 0), o.version)
    del clf.opset_import[:]
    clf.opset_import.extend(helper.make_opsetid(d, v) for d, v in sorted(ops.items()))
    onnx.checker.check_model(clf)
    return clf


def export_onnx(
    classifier: Any,
    regressor: Any,
    feature_names: list[str],
    class_names: list[str],
    path: str | Path,
    *,
    metadata: dict[str, Any],
    card: dict[str, Any],
) -> dict[str, Any]:
    """Write the ONNX model and its card (``<stem>.card.json``) atomically.

    Parameters
    ----------
    classifier, regressor : fitted HistGradientBoosting models
        The classifier's ``classes_`` index `class_names`.
    feature_names : list of str
        Names of the input columns.
    class_names : list of str
        Name of each class index; only those in ``classifier.classes_`` are
        recorded, in that order (the probability columns).
    path : str or Path
        Destination ``.onnx`` file.
    metadata : dict
        Extra ``metadata_props`` (values are JSON-encoded unless strings);
        must include ``training_data_sha256`` and ``conformal_quantile``.
    card : dict
        Model card content (metrics, data card summary, ...); the ONNX file's
        SHA-256, the metadata and the opset are added.

    Returns
    -------
    dict
        The model card as written.
    """
    model = build_onnx(classifier, regressor, len(feature_names))
    names = [class_names[int(c)] for c in classifier.classes_]
    props = {
        "model_kind": GBMFamily.model_kind,
        "class_names": names,
        "class_indices": [int(c) for c in classifier.classes_],
        "feature_names": list(feature_names),
        "beta_transform": "log",
        "opset": TARGET_OPSET,
        **metadata,
    }
    shapes = {
        "inputs": {INPUT_NAME: ["N", len(feature_names)]},
        "outputs": {"label": ["N"], "probabilities": ["N", len(names)], "log_beta": ["N", 1]},
    }
    return write_model(model, path, props, shapes, card)


def onnx_predict(path: str | Path, X: np.ndarray) -> dict[str, np.ndarray]:
    """Run the exported model: ``label``, ``probabilities`` and ``beta`` (= exp(log_beta))."""
    sess = onnx_session(path)
    label, proba, log_beta = sess.run(None, {INPUT_NAME: np.asarray(X, dtype=np.float32)})
    return {"label": label, "probabilities": proba, "beta": np.exp(log_beta[:, 0])}


def parity(path: str | Path, classifier: Any, regressor: Any, X: np.ndarray) -> dict[str, float]:
    """Largest ONNX-vs-sklearn differences on `X` (both fed the float32-rounded features).

    Returns
    -------
    dict
        ``max_abs_proba_diff``, ``max_rel_beta_diff`` and ``label_agreement``.
    """
    X32 = np.asarray(X, dtype=np.float32)
    out = onnx_predict(path, X32)
    Xd = X32.astype(np.float64)
    p = classifier.predict_proba(Xd)
    b = np.exp(regressor.predict(Xd))
    return {
        "max_abs_proba_diff": float(np.max(np.abs(out["probabilities"] - p))) if len(X) else 0.0,
        "max_rel_beta_diff": float(np.max(np.abs(out["beta"] - b) / b)) if len(X) else 0.0,
        "label_agreement": float(np.mean(out["label"] == classifier.predict(Xd))) if len(X) else 1,
    }
