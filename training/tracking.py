"""MLflow tracking of a training run (``import mlflow`` stays inside ``training/``).

Default store: ``sqlite:///mlflow.db``, a SQLite file in the current folder;
any MLflow tracking URI can be passed instead. With a SQLite store, a new
experiment keeps its artifacts in ``mlruns/`` beside the database file.
"""

from __future__ import annotations

import tempfile
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


def _artifact_location(uri: str) -> str | None:
    """For a SQLite store, artifacts go to ``mlruns/`` beside the database file (MLflow's
    default would be ``./mlruns`` under whatever folder the process runs in)."""
    if not uri.startswith("sqlite:///"):
        return None
    db = Path(uri.removeprefix("sqlite:///")).resolve()
    return (db.parent / "mlruns").as_uri()


def _clean_key(key: str) -> str:
    # MLflow allows alphanumerics, _ - . space : / ; keep the names readable
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
) -> str:
    """Log one training run and return its run id.

    Parameters
    ----------
    tracking_uri : str or None
        MLflow tracking URI; None uses :data:`DEFAULT_TRACKING_URI`.
    experiment : str
        Experiment name (created if missing).
    params : dict
        Flat parameters (values are stringified by MLflow).
    metrics : dict
        Flat metrics, e.g. ``gbm/accuracy``, ``geometric/noise_0.05/accuracy``;
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

    Returns
    -------
    str
        The MLflow run id.
    """
    import mlflow

    uri = tracking_uri or DEFAULT_TRACKING_URI
    mlflow.set_tracking_uri(uri)
    client = mlflow.MlflowClient(uri)
    if client.get_experiment_by_name(experiment) is None:
        client.create_experiment(experiment, artifact_location=_artifact_location(uri))
    mlflow.set_experiment(experiment)
    with mlflow.start_run(tags=tags or {}) as run:
        mlflow.log_params({_clean_key(k): v for k, v in params.items()})
        finite = {_clean_key(k): float(v) for k, v in metrics.items() if np.isfinite(v)}
        mlflow.log_metrics(finite)
        mlflow.log_artifact(str(data_card_path), artifact_path="data")
        for a in artifacts:
            mlflow.log_artifact(str(a), artifact_path="model")
        with tempfile.TemporaryDirectory() as tmp:
            for name, cm in confusions.items():
                png = confusion_png(cm, class_names, f"{name} (test)", Path(tmp) / f"{name}.png")
                mlflow.log_artifact(str(png), artifact_path="figures")
        return run.info.run_id
