"""A toy model family from outside the library: ridge regressions on the inclination features.

It exists to prove the family contract (:mod:`training.families.base`): the test
registers it (:func:`training.families.register_family`) and trains, exports,
serves and recalibrates it without any library file naming it. The models are
closed-form ridge regressions on standardised features: one on the one-hot class
(its scores through a softmax are the ``probabilities``) and one on log(beta);
the ONNX graph is written by hand (MatMul, Add, Softmax), standardisation folded
into the weights.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper
from pydantic import BaseModel, ConfigDict, Field

from stiffnet.features import FEATURE_NAMES
from training.families.base import TrainedModel, TrainingFamily
from training.onnx_export import onnx_session, write_model

from .serving import RidgeServing


class RidgeConfig(BaseModel):
    """The toy family's config section (``ridge:``)."""

    model_config = ConfigDict(extra="forbid")
    alpha: float = Field(1.0, gt=0.0, description="ridge penalty on standardised features")
    validation_fraction: float = Field(0.15, gt=0.0, lt=0.5)


def ridge_fit(X: np.ndarray, Y: np.ndarray, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """Weights and intercepts of ``Y ~ X`` with an L2 penalty, in the units of `X`."""
    mu, sd = X.mean(axis=0), X.std(axis=0)
    sd[sd == 0] = 1.0
    Z = (X - mu) / sd
    Yc = Y - Y.mean(axis=0)
    W = np.linalg.solve(Z.T @ Z + alpha * np.eye(Z.shape[1]), Z.T @ Yc)
    W = W / sd[:, None]
    return W, Y.mean(axis=0) - mu @ W


def softmax(s: np.ndarray) -> np.ndarray:
    e = np.exp(s - s.max(axis=1, keepdims=True))
    return e / e.sum(axis=1, keepdims=True)


def ridge_graph(Wc: np.ndarray, bc: np.ndarray, wb: np.ndarray, bb: np.ndarray) -> onnx.ModelProto:
    """``probabilities = softmax(X Wc + bc)``, ``log_beta = X wb + bb``."""
    init = [
        numpy_helper.from_array(a.astype(np.float32), n)
        for a, n in ((Wc, "Wc"), (bc, "bc"), (wb, "wb"), (bb, "bb"))
    ]
    nodes = [
        helper.make_node("MatMul", ["features", "Wc"], ["sc"]),
        helper.make_node("Add", ["sc", "bc"], ["scores"]),
        helper.make_node("Softmax", ["scores"], ["probabilities"], axis=1),
        helper.make_node("MatMul", ["features", "wb"], ["lb"]),
        helper.make_node("Add", ["lb", "bb"], ["log_beta"]),
    ]
    k, c = Wc.shape
    graph = helper.make_graph(
        nodes,
        "toy_ridge",
        [helper.make_tensor_value_info("features", TensorProto.FLOAT, ["N", k])],
        [
            helper.make_tensor_value_info("probabilities", TensorProto.FLOAT, ["N", c]),
            helper.make_tensor_value_info("log_beta", TensorProto.FLOAT, ["N", 1]),
        ],
        init,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    return model


class RidgeTraining(TrainingFamily):
    """The toy family's training half."""

    name = "ridge"
    config = RidgeConfig
    serving = RidgeServing

    def inputs(self, ds: Any, config: Any) -> np.ndarray:
        from training.transformers import InclinationFeatures, window_records

        return InclinationFeatures(True).fit_transform(window_records(ds))

    def inputs_from_metadata(self, ds: Any, metadata: dict[str, Any]) -> np.ndarray:
        return self.inputs(ds, None).astype(np.float32)

    def fit(
        self, X: np.ndarray, ds: Any, split: Any, config: Any, say: Callable[[str], None]
    ) -> TrainedModel:
        X = np.asarray(X, dtype=np.float32).astype(np.float64)
        label, beta, names = ds.column("label"), ds.column("beta"), ds.class_names
        tr = split.train
        Wc, bc = ridge_fit(X[tr], np.eye(len(names))[label[tr]], config.section.alpha)
        contact = tr & (label != 0)
        wb, bb = ridge_fit(X[contact], np.log(beta[contact])[:, None], config.section.alpha)

        def outputs(rows: np.ndarray) -> dict[str, np.ndarray]:
            return {"probabilities": softmax(rows @ Wc + bc), "log_beta": (rows @ wb + bb)[:, 0]}

        def export(path: Path, metadata: dict[str, Any], card: dict[str, Any]) -> dict:
            props = {
                "model_kind": RidgeServing.model_kind,
                "class_names": names,
                "class_indices": list(range(len(names))),
                "feature_names": FEATURE_NAMES,
                "beta_transform": "log",
                **metadata,
            }
            shapes = {"inputs": {"features": ["N", X.shape[1]]}, "outputs": {}}
            return write_model(ridge_graph(Wc, bc, wb, bb), path, props, shapes, card)

        def parity(path: Path, rows: np.ndarray) -> dict[str, float]:
            sess = onnx_session(path)
            p, lb = sess.run(None, {"features": np.asarray(rows, dtype=np.float32)})
            want = outputs(np.asarray(rows, dtype=np.float32).astype(np.float64))
            return {
                "max_abs_proba_diff": float(np.max(np.abs(p - want["probabilities"]))),
                "max_abs_log_beta_diff": float(np.max(np.abs(lb[:, 0] - want["log_beta"]))),
            }

        say(f"ridge fitted on {int(tr.sum())} windows")
        return TrainedModel(
            name=self.name,
            inputs=X,
            outputs=outputs(X),
            classes=np.arange(len(names)),
            export=export,
            parity=parity,
            params={"ridge.alpha": config.section.alpha},
        )
