"""MLflow tracking of a training run (``import mlflow`` stays inside ``training/``).

Default store: ``sqlite:///mlflow.db``, a SQLite file in the current folder;
any MLflow tracking URI can be passed instead. With a SQLite store, a new
experiment keeps its artifacts in ``mlruns/`` beside the database file.

A run holds what MLflow users compare in the UI: parameters, final metrics, the
per-epoch ``train_loss`` / ``val_loss`` as step metrics (CNN), and the exported
ONNX file as a *logged model* (``mlflow.onnx.log_model``: MLmodel with the input
signature read from the graph, the model card as its metadata, the ONNX Runtime
requirement) linked to the run's metrics, so ``models:/<model_id>`` loads it.

Public API for the other layers (the measurement loop imports nothing private):
:func:`use_experiment`, :func:`log_run` (one training run), :func:`parent_run` and
:func:`log_child_run` (a process of resumable steps: one parent, a nested run per step,
its model registered in the Model Registry), :func:`log_parent_artifact`,
:func:`log_onnx_model`, :func:`finite_metrics`, :func:`clean_key`,
:func:`artifact_location`.
"""

from __future__ import annotations

import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

DEFAULT_TRACKING_URI = "sqlite:///mlflow.db"


def confusion_png(cm: np.ndarray, class_names: list[str], title: str, path: str | Path) -> Path:
    """Draw a confusion matrix (rows: true, columns: predicted) to a PNG with matplotlib Agg.

    Parameters
    ----------
    cm : numpy.ndarray
        Square count matrix.
    class_names : list of str
        Axis labels.
    title : str
        Figure title.
    path : str or Path
        Destination file.

    Returns
    -------
    Path
        `path`.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.5), dpi=100)
    ax.imshow(cm, cmap="Blues")
    ax.set_xticks(range(len(class_names)), class_names, rotation=45, ha="right")
    ax.set_yticks(range(len(class_names)), class_names)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title)
    top = cm.max() if cm.size else 0
    for i in range(cm.shape[0]):
        for j in range(cm.shape[1]):
            color = "white" if cm[i, j] > 0.5 * top else "black"
            ax.text(j, i, str(int(cm[i, j])), ha="center", va="center", color=color)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)


def artifact_location(uri: str) -> str | None:
    """Where a new experiment of a store keeps its artifacts.

    For a SQLite store, ``mlruns/`` beside the database file (MLflow's default
    would be ``./mlruns`` under whatever folder the process runs in); None (MLflow's
    choice) for any other store.
    """
    if not uri.startswith("sqlite:///"):
        return None
    db = Path(uri.removeprefix("sqlite:///")).resolve()
    return (db.parent / "mlruns").as_uri()


def clean_key(key: str) -> str:
    """A parameter or metric name MLflow accepts (alphanumerics, ``_ - . space : /``)."""
    return "".join(c if c.isalnum() or c in "_-./ :" else "_" for c in key)


def log_run(
    *,
    tracking_uri: str | None,
    experiment: str,
    params: dict[str, Any],
    metrics: dict[str, float],
    data_card_path: str | Path,
    artifacts: list[str | Path],
    confusions: dict[str, np.ndarray],
    class_names: list[str],
    tags: dict[str, str] | None = None,
    history: list[dict[str, float]] | None = None,
    onnx_model: str | Path | None = None,
    run_name: str | None = None,
    start_time: float | None = None,
    dataset: dict[str, Any] | None = None,
    registered_model: str | None = None,
) -> dict[str, Any]:
    """Log one training run; returns its run id, logged model id and registered version.

    Parameters
    ----------
    tracking_uri : str or None
        MLflow tracking URI; None uses :data:`DEFAULT_TRACKING_URI`.
    experiment : str
        Experiment name (created if missing).
    params : dict
        Flat parameters (values are stringified by MLflow).
    metrics : dict
        Flat metrics, the same names for every family, e.g. ``accuracy``,
        ``recording/beta_coverage``, ``geometric/noise_0.05/accuracy``;
        non-finite values are skipped.
    data_card_path : str or Path
        The dataset's ``card.json``, logged under ``data/``.
    artifacts : list of path
        Files logged under ``model/`` (the ONNX file and its card).
    confusions : dict
        ``{"gbm": matrix, "geometric": matrix}``, drawn to PNGs under ``figures/``.
    class_names : list of str
        Confusion-matrix axis labels.
    tags : dict, optional
        Run tags.
    history : list of dict, optional
        Per-epoch entries (``epoch``, ``train_loss``, ``val_loss``): logged as
        step metrics ``train_loss`` and ``val_loss`` (step = epoch).
    onnx_model : str or Path, optional
        The exported ONNX file, logged as the run's logged model ``model``
        (card ``<stem>.card.json`` beside it as metadata).
    run_name : str, optional
        What ran (family, dataset, time); MLflow's random name without it.
    start_time : float, optional
        When the run began (seconds since the epoch): the run covers the training,
        not only its logging.
    dataset : dict, optional
        The training data's identity (``name``, ``digest``: the card's SHA-256,
        ``source``: its folder's URI, plus counts), logged as the run's input
        (``mlflow.log_input``, context ``training``).
    registered_model : str, optional
        Register the logged model under this name in the Model Registry (a new version).

    Returns
    -------
    dict
        ``run_id``, ``model_id`` and ``model_version`` (None when not logged or registered).
    """
    import mlflow

    exp_id = use_experiment(tracking_uri, experiment)
    client = mlflow.MlflowClient(tracking_uri or DEFAULT_TRACKING_URI)
    start_ms = int(1000 * start_time) if start_time is not None else None
    created = client.create_run(exp_id, start_time=start_ms, tags=tags or {}, run_name=run_name)
    out: dict[str, Any] = {"run_id": created.info.run_id, "model_id": None, "model_version": None}
    with mlflow.start_run(run_id=created.info.run_id):
        mlflow.log_params({clean_key(k): v for k, v in params.items()})
        if dataset is not None:
            log_dataset(dataset)
        finite = finite_metrics(metrics)
        mlflow.log_metrics(finite)
        for h in history or []:
            step = {k: float(v) for k, v in h.items() if k != "epoch" and np.isfinite(v)}
            mlflow.log_metrics(step, step=int(h["epoch"]))
        if onnx_model is not None:
            info = log_onnx_model(onnx_model)
            mlflow.log_metrics(finite, model_id=info.model_id)  # the model's own metrics
            out["model_id"] = info.model_id
            if registered_model:
                version = mlflow.register_model(info.model_uri, registered_model, tags=tags)
                out["model_version"] = int(version.version)
        mlflow.log_artifact(str(data_card_path), artifact_path="data")
        for a in artifacts:
            mlflow.log_artifact(str(a), artifact_path="model")
        with tempfile.TemporaryDirectory() as tmp:
            for name, cm in confusions.items():
                png = confusion_png(cm, class_names, f"{name} (test)", Path(tmp) / f"{name}.png")
                mlflow.log_artifact(str(png), artifact_path="figures")
    return out


def log_dataset(dataset: dict[str, Any]) -> None:
    """Log a dataset's identity as the active run's training input (no data is copied)."""
    import mlflow
    from mlflow.data.dataset_source_registry import resolve_dataset_source
    from mlflow.data.meta_dataset import MetaDataset

    with warnings.catch_warnings():
        # MLflow registers its local artifact source twice and says the URI is ambiguous
        warnings.filterwarnings("ignore", "The specified dataset source", UserWarning)
        source = resolve_dataset_source(str(dataset["source"]))  # file:// -> local artifact
    meta = MetaDataset(
        source,
        name=str(dataset["name"]),
        digest=str(dataset["digest"])[:36],  # MLflow keeps at most 36 characters
    )
    extra = {k: str(v) for k, v in dataset.items() if k not in ("name", "digest", "source")}
    mlflow.log_input(meta, context="training", tags={"sha256": str(dataset["digest"]), **extra})


def use_experiment(tracking_uri: str | None, experiment: str) -> str:
    """Point MLflow at ``tracking_uri`` and make ``experiment`` the active one.

    The experiment is created when missing (artifacts beside a SQLite store, see
    :func:`artifact_location`).

    Returns
    -------
    str
        The experiment id.
    """
    import mlflow

    uri = tracking_uri or DEFAULT_TRACKING_URI
    mlflow.set_tracking_uri(uri)
    client = mlflow.MlflowClient(uri)
    found = client.get_experiment_by_name(experiment)
    exp_id = (
        found.experiment_id
        if found is not None
        else client.create_experiment(experiment, artifact_location=artifact_location(uri))
    )
    mlflow.set_experiment(experiment_id=exp_id)
    return str(exp_id)


def finite_metrics(metrics: dict[str, float | None]) -> dict[str, float]:
    """Metrics with MLflow-safe names, None and non-finite values left out."""
    return {
        clean_key(k): float(v)
        for k, v in metrics.items()
        if v is not None and not isinstance(v, bool) and np.isfinite(v)
    }


def parent_run(tracking_uri: str | None, experiment: str, run_id: str | None, name: str,
               tags: dict[str, str] | None = None) -> str:  # fmt: skip
    """The id of the run ``run_id`` if the store has it, else of a new run ``name``.

    The run of a process made of several resumable steps (the measurement loop):
    each step is a child run (:func:`log_child_run`) and the parent carries the
    per-step metrics as a series.
    """
    import mlflow
    from mlflow.exceptions import MlflowException

    exp_id = use_experiment(tracking_uri, experiment)
    client = mlflow.MlflowClient(tracking_uri or DEFAULT_TRACKING_URI)
    if run_id:
        try:
            return client.get_run(run_id).info.run_id
        except MlflowException:
            pass  # another store, or the run was deleted: start a new parent
    run = client.create_run(exp_id, run_name=name, tags=tags or {})
    client.set_terminated(run.info.run_id)
    return run.info.run_id


def log_child_run(
    *,
    tracking_uri: str | None,
    experiment: str,
    parent_run_id: str,
    name: str,
    step: int,
    params: dict[str, Any],
    metrics: dict[str, float | None],
    tags: dict[str, str] | None = None,
    artifacts: Sequence[str | Path] = (),
    onnx_model: str | Path | None = None,
    registered_model: str | None = None,
) -> dict[str, Any]:
    """Log one step of a parent run as a nested run; optionally register its model.

    Parameters
    ----------
    tracking_uri, experiment : str
        Store and experiment (created if missing).
    parent_run_id : str
        From :func:`parent_run`; the step's metrics are also logged there with
        ``step`` (so the parent shows them against the step).
    name : str
        Run name.
    step : int
        Step index (tag ``stiffnet.step``).
    params, metrics : dict
        Flat; None and non-finite metrics are left out.
    tags : dict, optional
    artifacts : list of path
        Files logged under ``files/``.
    onnx_model : path, optional
        Logged as the run's model (:func:`log_onnx_model`, card as metadata).
    registered_model : str, optional
        Register that model under this name in the Model Registry (a new version).

    Returns
    -------
    dict
        ``run_id``, ``model_id``, ``model_uri``, ``model_version`` (None when not
        logged or registered).
    """
    import mlflow

    use_experiment(tracking_uri, experiment)
    client = mlflow.MlflowClient(tracking_uri or DEFAULT_TRACKING_URI)
    finite = finite_metrics(metrics)
    out: dict[str, Any] = {"model_id": None, "model_uri": None, "model_version": None}
    all_tags = {"stiffnet.step": str(step), **(tags or {})}
    with mlflow.start_run(run_name=name, parent_run_id=parent_run_id, tags=all_tags) as run:
        out["run_id"] = run.info.run_id
        mlflow.log_params({clean_key(k): str(v)[:500] for k, v in params.items()})
        mlflow.log_metrics(finite)
        for a in artifacts:
            mlflow.log_artifact(str(a), artifact_path="files")
        if onnx_model is not None:
            info = log_onnx_model(onnx_model)
            mlflow.log_metrics(finite, model_id=info.model_id)
            out["model_id"], out["model_uri"] = info.model_id, info.model_uri
            if registered_model:
                version = mlflow.register_model(info.model_uri, registered_model, tags=all_tags)
                out["model_version"] = int(version.version)
    for k, v in finite.items():
        client.log_metric(parent_run_id, k, v, step=step)
    return out


def log_parent_artifact(tracking_uri: str | None, run_id: str, path: str | Path) -> None:
    """Attach a file (e.g. a chart over all steps) to a finished run, under ``files/``."""
    import mlflow

    mlflow.MlflowClient(tracking_uri or DEFAULT_TRACKING_URI).log_artifact(
        run_id, str(path), artifact_path="files"
    )


def onnx_signature(model: Any) -> Any:
    """MLflow signature of an ONNX graph's inputs (dynamic dimensions as -1)."""
    from mlflow.models import ModelSignature
    from mlflow.types.schema import Schema, TensorSpec
    from onnx import helper

    specs = []
    for inp in model.graph.input:
        t = inp.type.tensor_type
        shape = tuple(d.dim_value if d.HasField("dim_value") else -1 for d in t.shape.dim)
        dtype = np.dtype(helper.tensor_dtype_to_np_dtype(t.elem_type))
        specs.append(TensorSpec(dtype, shape, inp.name))
    return ModelSignature(inputs=Schema(specs))


def log_onnx_model(path: str | Path) -> Any:
    """Log an exported ONNX file (and its card) as the active run's logged model ``model``.

    Returns
    -------
    mlflow.models.model.ModelInfo
        With ``model_id`` and ``model_uri``.
    """
    import json

    import mlflow
    import mlflow.onnx
    import onnx
    import onnxruntime

    p = Path(path)
    model = onnx.load(str(p))
    card_path = p.with_suffix(".card.json")
    card = json.loads(card_path.read_text()) if card_path.is_file() else {}
    flat = {k: v for k, v in card.items() if isinstance(v, str | int | float | bool)}
    return mlflow.onnx.log_model(
        model,
        name="model",
        signature=onnx_signature(model),
        metadata={"stiffnet_card": flat, "onnx_file": p.name},
        pip_requirements=[f"onnxruntime=={onnxruntime.__version__}"],  # no inference: offline
    )
