"""The predictor's model families: which windows they read and the ONNX input they build."""

from __future__ import annotations

import numpy as np
import pytest

from serving.families import families, family_for
from serving.families.base import spread_windows
from serving.families.cnn import CNNFamily
from serving.families.gbm import GBMFamily
from stiffnet.errors import StiffnetError
from stiffnet.features import FEATURE_NAMES
from stiffnet.features.windows import window_length, window_tensor


def test_registry_finds_the_modules_and_maps_model_kind_to_family():
    assert {"stiffnet.cnn": CNNFamily, "stiffnet.gbm": GBMFamily}.items() <= families().items()
    assert family_for("stiffnet.gbm") is GBMFamily and family_for("stiffnet.svm") is None
    assert (CNNFamily.input_name, GBMFamily.input_name) == ("windows", "features")
    # exactly one family's shipped model is the predictor's default
    assert [f for f in families().values() if f.default] == [CNNFamily]


def test_spread_windows_cover_first_and_last():
    assert spread_windows(10, 3).tolist() == [0, 4, 9]
    assert spread_windows(2, 3).tolist() == [0, 1]
    assert spread_windows(1, 3).tolist() == [0]


def test_cnn_reads_a_few_windows_and_builds_canonical_input():
    fam = CNNFamily({"canonical_rate": 16, "window_periods": 4, "delays": [0, 3]})
    assert fam.feature_windows(35, 3).tolist() == [0, 17, 34]
    rng = np.random.default_rng(0)
    n = window_length(500.0, 10.0, 4)
    W = rng.standard_normal((3, n))
    X = fam.model_input(W, 500.0, 10.0, np.empty((0, len(FEATURE_NAMES))))
    assert X.dtype == np.float32 and X.shape == (3, 2, 64)
    np.testing.assert_array_equal(X, window_tensor(list(W), 500.0, 10.0, 16, 4, (0, 3)))


def test_cnn_metadata_must_say_how_to_cut():
    with pytest.raises(StiffnetError, match="canonical_rate"):
        CNNFamily.check_metadata({"window_periods": 16, "delays": [0]}, "m.onnx")
    GBMFamily.check_metadata({}, "m.onnx")  # the GBM needs nothing beyond the features


@pytest.mark.parametrize("uses_fn", [True, False])
def test_gbm_reads_every_window_and_masks_fn_when_trained_without(uses_fn):
    fam = GBMFamily({"requires_natural_frequency": uses_fn})
    assert fam.feature_windows(5, 3).tolist() == [0, 1, 2, 3, 4]
    feats = np.arange(2 * len(FEATURE_NAMES), dtype=np.float64).reshape(2, -1)
    X = fam.model_input(np.zeros((2, 100)), 500.0, 10.0, feats)
    assert X.dtype == np.float32
    col = FEATURE_NAMES.index("period_natural")
    expect = feats[:, col] if uses_fn else [-1.0, -1.0]
    np.testing.assert_array_equal(X[:, col], expect)
    others = np.delete(np.arange(len(FEATURE_NAMES)), col)
    np.testing.assert_array_equal(X[:, others], feats[:, others])
    assert feats[0, col] == col  # the features passed in are not modified
