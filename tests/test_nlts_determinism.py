"""Kaplan-Glass determinism test (section 4.2.2)."""

import numpy as np
import pytest
from _lorenz import lorenz_x

from stiffnet.errors import SignalError
from stiffnet.nlts import VectorField, approximate_vector_field, determinism_factor, kaplan_glass


def test_periodic_signal_is_deterministic():
    x = np.sin(2 * np.pi * np.arange(5000) / 50)
    field, factor = kaplan_glass(x, dim=3, tau=12)
    assert factor > 0.8
    # passes through each box are parallel: resultant lengths are 1
    lengths = np.linalg.norm(field.mean_vectors[field.passes > 1], axis=1)
    np.testing.assert_allclose(lengths, 1.0, atol=0.02)


def test_lorenz_is_deterministic():
    _, factor = kaplan_glass(lorenz_x(5000), dim=3, tau=17)
    assert factor > 0.8


def test_white_noise_is_not_deterministic():
    x = np.random.default_rng(0).standard_normal(5000)
    _, factor = kaplan_glass(x, dim=3, tau=5)
    assert abs(factor) < 0.3


def test_field_shapes_and_counts():
    x = np.sin(2 * np.pi * np.arange(1000) / 50)
    y = np.c_[x[:-12], x[12:]]
    field = approximate_vector_field(y, n_boxes=4)
    k = field.passes.size
    assert field.boxes.shape == (k, 2) and field.mean_vectors.shape == (k, 2)
    assert field.boxes.min() >= 0 and field.boxes.max() <= 3
    # 20 periods, each box on the circle is crossed once per period (first/last runs dropped)
    assert field.passes.max() <= 20 and field.passes.min() >= 1


def test_factor_formula_random_walk_correction():
    # Two boxes: parallel passes (score 1) and two opposite passes (|V| = 0, score -1).
    field = VectorField(
        boxes=np.array([[0, 0], [1, 1]]),
        mean_vectors=np.array([[1.0, 0.0], [0.0, 0.0]]),
        passes=np.array([6, 2]),
    )
    assert determinism_factor(field) == pytest.approx((6 * 1 + 2 * -1) / 8)


def test_factor_needs_revisited_boxes():
    field = VectorField(np.zeros((1, 2), int), np.ones((1, 2)), np.array([1]))
    with pytest.raises(SignalError, match="visited"):
        determinism_factor(field)
