"""What a family of ONNX models reads from a recording's windows: the predictor's model interface.

The predictor cuts a recording into windows, asks its model's family which
windows the geometric cross-check analyses (the inclination features of
:func:`stiffnet.features.features_and_estimate`) and what the ONNX model's
input is, runs the model and aggregates its outputs. A family is one subclass
of :class:`ModelFamily` in one module beside this one, registered by its
``model_kind`` metadata (:mod:`serving.families`); the predictor holds no branch
per family. The serving half imports only numpy, scipy and onnxruntime; the
training half is :mod:`training.families`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from stiffnet.errors import StiffnetError


class ModelFamily(ABC):
    """One family of stiffnet ONNX models (the metadata of one model in hand).

    Attributes
    ----------
    kind : str
        Short name reported to users (``cnn``, ``gbm``).
    model_kind : str
        The ``model_kind`` metadata value of the family's models.
    input_name : str
        The name of the ONNX model's one input.
    required_metadata : tuple of str
        Metadata keys the family needs to build the model's input.
    default : bool
        True for the one family whose shipped model (``models/KIND.onnx``) the
        predictor loads when no model is named.
    metadata : dict
        The model's decoded metadata.
    """

    kind: ClassVar[str]
    model_kind: ClassVar[str]
    input_name: ClassVar[str]
    required_metadata: ClassVar[tuple[str, ...]] = ()
    default: ClassVar[bool] = False

    def __init__(self, metadata: dict[str, Any]) -> None:
        self.metadata = metadata

    @classmethod
    def check_metadata(cls, metadata: dict[str, Any], where: object) -> None:
        """Refuse a model whose metadata lacks what the family needs."""
        for key in cls.required_metadata:
            if key not in metadata:
                raise StiffnetError(f"{where}: {cls.kind.upper()} metadata lacks {key!r}")

    @abstractmethod
    def feature_windows(self, n_windows: int, geometric_windows: int) -> np.ndarray:
        """Indices of the windows whose inclination features the predictor computes.

        Parameters
        ----------
        n_windows : int
            Windows in the recording.
        geometric_windows : int
            The predictor's bound on the windows the geometric cross-check analyses
            (a family whose model reads the features of every window may exceed it).
        """

    @abstractmethod
    def model_input(
        self, windows: np.ndarray, fs_hz: float, natural_frequency_hz: float, features: np.ndarray
    ) -> np.ndarray:
        """The ONNX model's input for `windows`.

        Parameters
        ----------
        windows : numpy.ndarray
            ``(N, n)`` equal-length, non-constant windows at the recording's rate.
        fs_hz, natural_frequency_hz : float
            Sampling rate and natural frequency in Hz.
        features : numpy.ndarray
            Inclination features of the windows :meth:`feature_windows` chose, one row each.

        Returns
        -------
        numpy.ndarray
            float32, one row per window.
        """


def spread_windows(n_windows: int, k: int) -> np.ndarray:
    """Up to `k` window indices spread evenly over `n_windows` (first and last included)."""
    k = min(k, n_windows)
    return np.unique(np.round(np.linspace(0, n_windows - 1, k)).astype(int))
