"""Inclination features: invariances, fill values, batching, the sklearn transformer."""

import subprocess
import sys

import numpy as np
import pytest
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from stiffnet.config import validate_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.dataset.generate import generate_dataset
from stiffnet.dataset.store import load_dataset
from stiffnet.errors import SignalError
from stiffnet.features import (
    FEATURE_NAMES,
    FILL_VALUES,
    feature_matrix,
    features_and_estimate,
    inclination_features,
)
from training.transformers import SKLEARN_CHECKS, InclinationFeatures, window_records

TINY = {
    "seed": 3,
    "n_trajectories": 10,
    "shard_size": 10,
    "windows": {"duration_periods": 8, "per_trajectory": 1},
    "sweep": {"fs_ratio": [50, 80], "noise_levels": [0.0, 0.05]},
    "solver": {"settle_tolerance": 0.1, "batch_size": 10},
}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("feat") / "ds"
    generate_dataset(validate_config(SimulationConfig, TINY), out)
    return load_dataset(out)


def test_names_and_fills_consistent():
    assert len(FEATURE_NAMES) == len(set(FEATURE_NAMES)) == len(FILL_VALUES)
    assert set(FILL_VALUES) == set(FEATURE_NAMES)


def test_gain_and_polarity_invariance(tiny):
    fs, fn = tiny.column("fs_hz"), tiny.column("natural_frequency_hz")
    n_contact = 0
    for w, f, n in zip(tiny.windows(), fs, fn, strict=True):
        base = inclination_features(w, f, n)
        assert base.dtype == np.float64 and base.shape == (len(FEATURE_NAMES),)
        assert np.isfinite(base).all()
        n_contact += int(base[FEATURE_NAMES.index("contact_detected")])
        for g in (1000.0, -1.0, -1000.0):
            other = inclination_features(g * w.astype(np.float64), f, n)
            np.testing.assert_allclose(other, base, rtol=1e-9, atol=1e-9)
    assert n_contact >= 5


def test_no_contact_fill_values():
    fs = 500.0
    t = np.arange(4000) / fs
    rng = np.random.default_rng(0)
    x = np.sin(2 * np.pi * 9.5 * t) + 0.01 * rng.standard_normal(t.size)
    f, est = features_and_estimate(x, fs, natural_frequency_hz=None)
    assert est is not None and not est.contact_detected
    assert np.isfinite(f).all()
    for name in ("contact_detected", "polynomial_after_deg", "spike_width_half_height"):
        assert f[FEATURE_NAMES.index(name)] == FILL_VALUES[name]
    assert f[FEATURE_NAMES.index("period_natural")] == -1.0
    f2 = inclination_features(x, fs, 9.5)
    assert f2[FEATURE_NAMES.index("period_natural")] == pytest.approx(1.0, rel=0.02)


def test_geometry_failure_is_filled_not_raised():
    # two periods only: the geometric chain refuses, the features are filled
    x = np.sin(2 * np.pi * np.arange(200) / 100.0)
    f, est = features_and_estimate(x, 100.0)
    assert est is None and f[FEATURE_NAMES.index("geometry_ok")] == 0.0
    assert np.isfinite(f).all()
    with pytest.raises(SignalError):
        inclination_features(np.ones(100), 100.0)
    with pytest.raises(SignalError):
        inclination_features(np.full(100, np.nan), 100.0)


def test_feature_matrix_matches_rows_and_jobs(tiny):
    w, fs = tiny.windows(), tiny.column("fs_hz")
    X = feature_matrix(w, fs)
    assert X.shape == (len(w), len(FEATURE_NAMES))
    np.testing.assert_array_equal(X[3], inclination_features(w[3], fs[3]))
    np.testing.assert_array_equal(feature_matrix(w, fs, n_jobs=2), X)
    assert feature_matrix([], 100.0).shape == (0, len(FEATURE_NAMES))


def test_transformer_in_pipeline(tiny):
    recs = window_records(tiny)
    assert set(recs[0]) == {"accel", "fs_hz", "natural_frequency_hz"}
    pipe = make_pipeline(InclinationFeatures(), StandardScaler())
    Z = pipe.fit_transform(recs)
    assert Z.shape == (len(tiny), len(FEATURE_NAMES)) and np.isfinite(Z).all()
    tr = InclinationFeatures(use_natural_frequency=False)
    X = tr.fit_transform(tiny)  # a Dataset works too
    assert (X[:, FEATURE_NAMES.index("period_natural")] == -1.0).all()
    assert list(tr.get_feature_names_out()) == FEATURE_NAMES
    assert tr.get_params() == {"use_natural_frequency": False, "n_jobs": 1}


def test_features_import_no_heavy_packages():
    code = (
        "import sys, stiffnet.features; "
        "bad = [m for m in ('sklearn', 'torch', 'mlflow', 'onnx') if m in sys.modules]; "
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_records_with_unknown_natural_frequency(tiny):
    recs = window_records(tiny)[:2]
    recs = [
        {"accel": recs[0]["accel"], "fs_hz": recs[0]["fs_hz"]},
        {**recs[1], "natural_frequency_hz": None},
    ]
    X = InclinationFeatures().fit_transform(recs)
    assert (X[:, FEATURE_NAMES.index("period_natural")] == -1.0).all()


@pytest.mark.parametrize("check", SKLEARN_CHECKS)
def test_transformer_passes_the_sklearn_checks_that_apply(check):
    import sklearn.utils.estimator_checks as ec

    getattr(ec, check)("InclinationFeatures", InclinationFeatures())


def test_transformer_tags_and_data_contract(tiny):
    import pickle

    from sklearn.base import clone
    from sklearn.utils import get_tags

    tags = get_tags(InclinationFeatures())
    assert tags.estimator_type is None and tags.transformer_tags is not None
    assert not tags.requires_fit and tags.input_tags.dict and not tags.input_tags.two_d_array
    assert InclinationFeatures.__mro__.index(TransformerMixin) < InclinationFeatures.__mro__.index(
        BaseEstimator
    )
    recs = window_records(tiny)[:6]
    tr = InclinationFeatures()
    X = tr.transform(recs)  # stateless: no fit needed
    assert tr.fit(recs) is tr
    np.testing.assert_array_equal(tr.fit_transform(recs), X)  # fit_transform == transform
    np.testing.assert_array_equal(tr.fit(recs).transform(recs), X)  # idempotent
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(tr)).transform(recs), X)
    np.testing.assert_array_equal(clone(tr).transform(recs), X)
    assert X.dtype == np.float64 and X.shape[1] == len(tr.get_feature_names_out())
    df = InclinationFeatures().set_output(transform="pandas").fit_transform(recs)
    assert list(df.columns) == FEATURE_NAMES and np.array_equal(df.to_numpy(), X)
