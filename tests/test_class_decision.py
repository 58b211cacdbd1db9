"""The class from the beta head near a class edge: the rule, its config and the predictor's use."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest

import serving.predictor as sp
from serving.aggregate import segments
from serving.predictor import Predictor
from stiffnet.errors import ConfigError
from stiffnet.uncertainty import RecordingEstimate
from stiffnet.uncertainty import class_decision as cd
from stiffnet.uncertainty.class_decision import (
    BETA_HEAD,
    CLASS_HEAD,
    FamilyRule,
    beta_class_index,
    decide_class,
)

ROOT = Path(__file__).resolve().parents[1]
NAMES = ["no_contact", "soft", "medium", "hard", "very_hard"]
EDGES = [5.0, 15.0, 35.0, 60.0, 100.0]
RULE = FamilyRule(max_head_probability=0.8)


def _estimate(p: list[float], beta: float | None) -> RecordingEstimate:
    proba = np.asarray(p, dtype=float)
    log_beta = None if beta is None else math.log(beta)
    return RecordingEstimate(proba, int(np.argmax(proba)), log_beta, 0.2, 4)


@pytest.mark.parametrize(
    ("beta", "name"),
    [(3.0, "soft"), (14.99, "soft"), (15.0, "medium"), (34.9, "medium"), (35.0, "hard"),
     (59.0, "hard"), (60.0, "very_hard"), (250.0, "very_hard")],
)  # fmt: skip
def test_the_beta_class_is_the_bin_holding_beta_with_open_outer_classes(beta, name):
    assert NAMES[beta_class_index(math.log(beta), NAMES, EDGES)] == name


def test_no_beta_class_without_beta_or_with_edges_that_do_not_match():
    assert beta_class_index(None, NAMES, EDGES) is None
    assert beta_class_index(math.log(20.0), NAMES, EDGES[:-1]) is None
    assert beta_class_index(math.log(20.0), NAMES, None) is None
    # a model without a no_contact class: the edges bound all its classes
    assert beta_class_index(math.log(20.0), NAMES[1:], EDGES) == 1


def test_the_beta_head_decides_a_neighbouring_class_when_the_class_head_is_not_decisive():
    # class head: hard at 0.6 (< 0.8); beta 33 lies in medium, the neighbour below the edge 35
    d = decide_class(_estimate([0.0, 0.05, 0.35, 0.6, 0.0], 33.0), NAMES, EDGES, RULE)
    assert (d.label, d.class_head, d.beta_class, d.decided_by) == (2, 3, 2, BETA_HEAD)


@pytest.mark.parametrize(
    ("p", "beta", "why"),
    [
        ([0.0, 0.0, 0.15, 0.85, 0.0], 33.0, "decisive class head (0.85 >= 0.8)"),
        ([0.0, 0.0, 0.2, 0.8, 0.0], 33.0, "at the threshold the class head decides"),
        ([0.0, 0.3, 0.1, 0.6, 0.0], 12.0, "beta two classes away: not near an edge"),
        ([0.0, 0.05, 0.35, 0.6, 0.0], 40.0, "the heads agree"),
        ([0.6, 0.3, 0.1, 0.0, 0.0], None, "no contact: no beta to read"),
    ],
)
def test_otherwise_the_class_head_decides(p, beta, why):
    est = _estimate(p, beta)
    d = decide_class(est, NAMES, EDGES, RULE)
    assert d.label == est.label and d.decided_by == CLASS_HEAD, why


def test_without_a_rule_the_class_head_decides():
    d = decide_class(_estimate([0.0, 0.05, 0.35, 0.6, 0.0], 33.0), NAMES, EDGES, None)
    assert (d.label, d.decided_by) == (3, CLASS_HEAD)


def test_the_shipped_config_is_valid_and_a_bad_one_is_refused_in_one_line(tmp_path, monkeypatch):
    cd.class_decision_config.cache_clear()
    cfg = cd.class_decision_config()
    assert set(cfg.families) <= {"cnn", "gbm"}
    for rule in cfg.families.values():
        assert 0.5 < rule.max_head_probability <= 1.0
    (tmp_path / cd.CLASS_DECISION_CONFIG).write_text(
        "families:\n  gbm: {max_head_probability: 1.5}\n", encoding="utf-8"
    )
    monkeypatch.setattr("stiffnet.shipped.REPO_CONFIGS_DIR", tmp_path)
    cd.class_decision_config.cache_clear()
    try:
        with pytest.raises(ConfigError) as err:
            cd.class_decision_config()
        assert "max_head_probability" in str(err.value) and "\n" not in str(err.value)
    finally:
        cd.class_decision_config.cache_clear()


def test_segments_take_their_class_from_the_same_rule():
    # two tiles of two windows: the first near the medium/hard edge, the second deep in hard
    proba = np.array([[0, 0, 0.4, 0.6, 0]] * 2 + [[0, 0, 0.05, 0.95, 0]] * 2, dtype=float)
    out = {"probabilities": proba, "log_beta": np.log([33.0, 33.0, 45.0, 45.0])}
    starts = np.arange(4) * 100

    def decide(est):
        return decide_class(est, NAMES, EDGES, RULE)

    segs = segments(out, starts, 100, 400, 100.0, 2, NAMES, 0, decide)
    assert [(s["class"], s["class_decided_by"]) for s in segs] == [
        ("medium", BETA_HEAD),
        ("hard", CLASS_HEAD),
    ]
    assert segs[0]["probabilities"]["hard"] == pytest.approx(0.6)  # reported as they are
    plain = segments(out, starts, 100, 400, 100.0, 2, NAMES, 0)
    assert [s["class"] for s in plain] == ["hard", "hard"]


def test_the_predictor_reports_the_beta_heads_class_and_the_probabilities_as_they_are(
    monkeypatch,
):
    pred = Predictor.load(ROOT / "models" / "gbm.onnx")
    n = 6  # the class head says hard (0.6), the beta head 33 (medium), every window

    def run_model(a, starts, n_win, fs, fn, geometric_windows=None):
        k = len(starts)
        proba = np.tile([0.0, 0.05, 0.35, 0.6, 0.0], (k, 1))
        return ({"probabilities": proba, "log_beta": np.full(k, math.log(33.0))},
                np.empty((0, 0)), [])  # fmt: skip

    refused = {"class": None, "beta": None, "beta_interval": None, "reason": "test"}
    monkeypatch.setattr(pred, "_run_model", run_model)
    monkeypatch.setattr(sp, "restoring_force_check", lambda *a, **k: refused)
    monkeypatch.setattr(sp, "family_rule", lambda kind: RULE if kind == "gbm" else None)
    fs, fn = 1000.0, 9.48
    t = np.arange(int(fs * 16 / fn * n)) / fs
    r = pred.predict(np.sin(2 * np.pi * fn * t), fs, natural_frequency_hz=fn)
    assert r["class"] == "medium" and r["class_decided_by"] == BETA_HEAD
    assert r["probabilities"]["hard"] == pytest.approx(0.6)
    assert "medium (from beta)" in _terminal(r)  # predict's table says which head decided
    assert r["beta"] == pytest.approx(33.0)
    assert all(s["class"] == "medium" for s in r["segments"])
    assert r["restoring_force_agreement"] is None
    # the class_beta check still compares the two heads: hard (35-60) against beta ~33
    fired = (r["alarm"] or {}).get("fired", [])
    lo, hi = r["beta_interval"]
    assert ("class_beta" in fired) == (hi < 35.0)
    monkeypatch.setattr(sp, "family_rule", lambda kind: None)
    r = pred.predict(np.sin(2 * np.pi * fn * t), fs, natural_frequency_hz=fn)
    assert r["class"] == "hard" and r["class_decided_by"] == CLASS_HEAD
    assert "from beta" not in _terminal(r)


def _terminal(result: dict) -> str:
    from rich.console import Console

    from stiffnet.cli.predict import result_tables

    console = Console(record=True, width=200, file=io.StringIO())
    console.print(*result_tables(result, "r"))
    return console.export_text()
