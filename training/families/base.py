"""The contract of a model family's training half (the serving half: :mod:`serving.families`).

A family is one package under ``training/families/`` (plus its serving module under
``serving/families/`` and its ``configs/train/NAME.yaml``): a :class:`TrainingFamily`
subclass in the package's ``__init__`` declares

* its name, its config section (a pydantic model; ``config.NAME`` in
  :class:`training.config.TrainConfig`) and its serving half (a
  :class:`serving.families.base.ModelFamily`, which reads only numpy, scipy and
  onnxruntime);
* :meth:`~TrainingFamily.inputs`: the model's input for every window of a dataset;
* :meth:`~TrainingFamily.fit`: the fitted model as a :class:`TrainedModel` (its
  outputs on every window, its ONNX export with the family's metadata, its parity
  check), which :func:`training.finish.finish_training` calibrates, evaluates,
  exports and tracks the same way for every family;
* :meth:`~TrainingFamily.inputs_from_metadata`: the input an exported model needs,
  rebuilt from its ONNX metadata (what :mod:`training.recalibrate` runs the model on).

The registry (:mod:`training.families`) finds the packages; a family defined
elsewhere (a plugin, a test) joins with :func:`training.families.register_family`.
Heavy libraries (torch, scikit-learn) are imported inside the methods, so listing or
validating families stays cheap.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from pydantic import BaseModel

if TYPE_CHECKING:
    from serving.families.base import ModelFamily
    from training.config import TrainConfig
    from training.split import Split


@dataclass
class TrainedModel:
    """A fitted model of one family, as :func:`training.finish.finish_training` needs it.

    Attributes
    ----------
    name : str
        The family (``NAME.onnx``, the card's ``model``, the MLflow ``family``).
    inputs : numpy.ndarray
        The model's input for every window of the dataset (the parity check's rows).
    outputs : dict of numpy.ndarray
        The model's outputs on every window, by ONNX output name: ``probabilities``
        and ``log_beta``, and ``log_beta_scale`` and ``embedding`` where the family has them.
    classes : numpy.ndarray
        The class index of each ``probabilities`` column.
    export : callable
        ``export(onnx_path, metadata, card) -> card``: writes ``NAME.onnx`` and its card.
    parity : callable
        ``parity(onnx_path, X) -> dict``: the ONNX model against the fitted one on rows `X`.
    metadata, card : dict
        The family's own ONNX metadata and model-card entries.
    versions : dict
        The training library's version, first in the card.
    params, metrics : dict
        The family's MLflow parameters and extra metrics.
    summary, timing : dict
        Extra ``summary.json`` entries and the seconds of the family's own steps.
    history : list of dict, optional
        Per-epoch losses, logged with the run.
    """

    name: str
    inputs: np.ndarray
    outputs: dict[str, np.ndarray]
    classes: np.ndarray
    export: Callable[[Path, dict[str, Any], dict[str, Any]], dict[str, Any]]
    parity: Callable[[Path, np.ndarray], dict[str, float]]
    metadata: dict[str, Any] = field(default_factory=dict)
    card: dict[str, Any] = field(default_factory=dict)
    versions: dict[str, str] = field(default_factory=dict)
    params: dict[str, Any] = field(default_factory=dict)
    metrics: dict[str, float] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    timing: dict[str, float] = field(default_factory=dict)
    history: list[dict[str, float]] | None = None


class TrainingFamily(ABC):
    """One model family's training half (see the module notes).

    Attributes
    ----------
    name : str
        Short name: ``--family NAME``, the config section ``NAME:``, ``NAME.onnx``.
    config : type of pydantic.BaseModel
        The family's config section; it has a ``validation_fraction`` (training
        trajectories held out for early stopping, part of the trajectory split).
    serving : type of serving.families.base.ModelFamily
        The family's serving half (its ``model_kind`` names the family's models).
    defaults : tuple of str
        The commands that train this family when none is named (``train``, ``loop``).
    loop_settings : dict
        The measurement loop's settings over ``configs/train/NAME.yaml`` (smaller
        datasets than the shipped model's, so fewer epochs and a wall-clock guard).
    """

    name: ClassVar[str]
    config: ClassVar[type[BaseModel]]
    serving: ClassVar[type[ModelFamily]]
    defaults: ClassVar[tuple[str, ...]] = ()
    loop_settings: ClassVar[dict[str, Any]] = {}

    @abstractmethod
    def inputs(self, ds: Any, config: TrainConfig) -> np.ndarray:
        """The model's input for every window of `ds` (a :class:`stiffnet.dataset.store.Dataset`).

        Raises
        ------
        StiffnetError
            If the dataset lacks what the family needs.
        """

    @abstractmethod
    def fit(
        self,
        X: np.ndarray,
        ds: Any,
        split: Split,
        config: TrainConfig,
        say: Callable[[str], None],
    ) -> TrainedModel:
        """Fit the model on the ``train`` rows of `X` (early-stopping on ``val``)."""

    @abstractmethod
    def inputs_from_metadata(self, ds: Any, metadata: dict[str, Any]) -> np.ndarray:
        """The input an exported model of this family reads, from its ONNX metadata."""

    @classmethod
    def check(cls) -> None:
        """Refuse a family class that does not declare the contract."""
        from serving.families.base import ModelFamily

        for attr in ("name", "config", "serving"):
            if not hasattr(cls, attr):
                raise TypeError(f"model family {cls.__name__} does not declare {attr!r}")
        if not (isinstance(cls.config, type) and issubclass(cls.config, BaseModel)):
            raise TypeError(f"{cls.__name__}.config must be a pydantic model")
        if "validation_fraction" not in cls.config.model_fields:
            raise TypeError(f"{cls.__name__}.config must have a validation_fraction")
        if not (isinstance(cls.serving, type) and issubclass(cls.serving, ModelFamily)):
            raise TypeError(f"{cls.__name__}.serving must be a serving ModelFamily")
