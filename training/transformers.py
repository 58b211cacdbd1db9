"""scikit-learn transformer wrapping :func:`stiffnet.features.inclination_features`.

Input type: a **sequence of window records**, each a mapping with keys
``"accel"`` (1-D array, any gain and polarity), ``"fs_hz"`` (float) and
optionally ``"natural_frequency_hz"`` (float or None). A
:class:`stiffnet.dataset.store.Dataset` or a pyarrow table with those columns
is accepted too and converted by :func:`window_records`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pyarrow as pa
from sklearn.base import BaseEstimator, TransformerMixin

from stiffnet.dataset.store import Dataset
from stiffnet.features import FEATURE_NAMES, feature_matrix

WindowRecords = Sequence[Mapping[str, Any]]


def window_records(data: Dataset | pa.Table | WindowRecords) -> list[Mapping[str, Any]]:
    """Normalise the accepted inputs to a list of window records.

    Parameters
    ----------
    data : Dataset, pyarrow.Table or sequence of mappings
        Windows; a table needs columns ``accel`` and ``fs_hz`` (and optionally
        ``natural_frequency_hz``).

    Returns
    -------
    list of dict
        One ``{"accel", "fs_hz", "natural_frequency_hz"}`` record per window.
    """
    if isinstance(data, pa.Table):
        data = Dataset(data, {})
    if isinstance(data, Dataset):
        fs = data.column("fs_hz")
        has_fn = "natural_frequency_hz" in data.table.column_names
        fn = data.column("natural_frequency_hz") if has_fn else [None] * len(fs)
        return [
            {"accel": w, "fs_hz": float(f), "natural_frequency_hz": n}
            for w, f, n in zip(data.windows(), fs, fn, strict=True)
        ]
    return list(data)


class InclinationFeatures(TransformerMixin, BaseEstimator):
    """Window records -> inclination feature matrix (stateless).

    scikit-learn conventions: mixins before :class:`~sklearn.base.BaseEstimator`;
    tags say what is true - the input is a sequence of records (mappings), not a
    2-D array (``input_tags.dict``, ``two_d_array=False``), and nothing is learned
    (``requires_fit=False``). ``check_estimator`` therefore runs only its clone
    check (it cannot build records); ``tests/test_features.py`` runs every check
    that needs no 2-D data (:data:`SKLEARN_CHECKS`) plus the data checks with real
    window records (fit/transform agreement, idempotence, pickling, cloning,
    feature names, ``set_output``).

    Parameters
    ----------
    use_natural_frequency : bool, default True
        Pass each record's ``natural_frequency_hz`` to the features; if False,
        feature ``period_natural`` is always the fill value -1 (for models
        served where the natural frequency is unknown).
    n_jobs : int, default 1
        Worker processes for the feature extraction (-1: one per CPU).
    """

    def __init__(self, use_natural_frequency: bool = True, n_jobs: int = 1) -> None:
        self.use_natural_frequency = use_natural_frequency
        self.n_jobs = n_jobs

    def fit(self, X: Any, y: Any = None) -> InclinationFeatures:
        """Nothing to learn; records the number of output features.

        Parameters
        ----------
        X : Dataset, pyarrow.Table or sequence of mappings
            Window records (unused).
        y : ignored

        Returns
        -------
        InclinationFeatures
            self.
        """
        self.n_features_out_ = len(FEATURE_NAMES)
        return self

    def transform(self, X: Any) -> np.ndarray:
        """Feature matrix of the windows.

        Parameters
        ----------
        X : Dataset, pyarrow.Table or sequence of mappings
            Window records (see the module notes).

        Returns
        -------
        numpy.ndarray
            Shape ``(n_windows, len(FEATURE_NAMES))``, float64, finite.
        """
        recs = window_records(X)
        fn = [r.get("natural_frequency_hz") for r in recs] if self.use_natural_frequency else None
        return feature_matrix(
            [r["accel"] for r in recs], [r["fs_hz"] for r in recs], fn, n_jobs=self.n_jobs
        )

    def get_feature_names_out(self, input_features: Any = None) -> np.ndarray:
        """Names of the output features.

        Parameters
        ----------
        input_features : ignored

        Returns
        -------
        numpy.ndarray
            :data:`stiffnet.features.FEATURE_NAMES` as an object array.
        """
        return np.asarray(FEATURE_NAMES, dtype=object)

    def __sklearn_tags__(self) -> Any:
        """Stateless; the input is a sequence of records (mappings), not a 2-D array."""
        tags = super().__sklearn_tags__()
        tags.requires_fit = False
        tags.input_tags.two_d_array = False
        tags.input_tags.dict = True
        tags.transformer_tags.preserves_dtype = ["float64"]  # features are float64
        return tags


#: scikit-learn estimator checks that apply to this transformer without 2-D input
#: (run by the tests; the data checks are done with window records instead).
SKLEARN_CHECKS = (
    "check_estimator_cloneable",
    "check_estimator_repr",
    "check_no_attributes_set_in_init",
    "check_parameters_default_constructible",
    "check_get_params_invariance",
    "check_set_params",
    "check_do_not_raise_errors_in_init_or_set_params",
    "check_estimator_tags_renamed",
    "check_valid_tag_types",
    "check_mixin_order",
)
