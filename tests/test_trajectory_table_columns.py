"""The recording-level calibration reads a model's probability columns by their classes.

A GBM trained where every window has contact (a loop iteration at a campaign's operating
points) has no ``no_contact`` column: its columns are the classes 1..4. The trajectory
table, from which the recording-level interval, the alarm's thresholds and the test
trajectories' metrics are computed, must read column 0 as ``soft`` there, as the predictor
does from the model's ``class_names``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from training.recalibrate import column_classes
from training.uncertainty_calibration import trajectory_metrics, trajectory_table


def _windows(columns: int, picks: list[int], log_betas: list[float], per: int = 4):
    """``per`` windows per trajectory, each confident in its column ``picks[j]``."""
    proba, lb, traj = [], [], []
    for j, (c, b) in enumerate(zip(picks, log_betas, strict=True)):
        p = np.full(columns, 0.02)
        p[c] = 1.0 - 0.02 * (columns - 1)
        proba += [p] * per
        lb += [b] * per
        traj += [j] * per
    return np.array(traj), np.array(proba), np.array(lb)


def test_a_model_without_a_no_contact_column_reads_column_zero_as_soft():
    # columns soft, medium, hard, very_hard (class indices 1..4); truths soft, medium, very_hard
    traj, proba, lb = _windows(4, [0, 1, 3], [np.log(8.0), np.log(20.0), np.log(80.0)])
    label = np.repeat([1, 2, 4], 4)
    beta = np.repeat([8.0, 20.0, 80.0], 4)
    outputs = {"probabilities": proba, "log_beta": lb}
    table = trajectory_table(traj, label, beta, outputs, classes=np.array([1, 2, 3, 4]))
    assert table.pred.tolist() == [1, 2, 4]
    # the soft trajectory has contact: its beta is read, not dropped as no-contact
    assert np.all(np.isfinite(table.log_beta))
    assert np.exp(table.log_beta) == pytest.approx([8.0, 20.0, 80.0])
    m = trajectory_metrics(table, 1.0)
    assert m["accuracy"] == 1.0
    assert m["beta_mape"] == pytest.approx(0.0, abs=1e-12)


def test_a_model_with_a_no_contact_column_is_read_as_before():
    traj, proba, lb = _windows(5, [0, 1, 4], [0.0, np.log(8.0), np.log(80.0)])
    label = np.repeat([0, 1, 4], 4)
    beta = np.repeat([1.0, 8.0, 80.0], 4)
    outputs = {"probabilities": proba, "log_beta": lb}
    for classes in (None, np.arange(5)):
        table = trajectory_table(traj, label, beta, outputs, classes=classes)
        assert table.pred.tolist() == [0, 1, 4]
        assert np.isnan(table.log_beta[0]) and np.all(np.isfinite(table.log_beta[1:]))


def test_column_classes_from_a_card():
    assert column_classes({"class_indices": [1, 2, 3, 4]}).tolist() == [1, 2, 3, 4]
    assert column_classes({"class_indices": json.dumps([0, 1, 2])}).tolist() == [0, 1, 2]
    assert column_classes({}) is None
