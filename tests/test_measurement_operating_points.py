"""The loop's training world at the campaign's own operating points."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from campaign_helpers import MANIFEST

from stiffnet.campaign.manifest import ManifestRow
from stiffnet.config import load_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.dataset.store import load_dataset
from stiffnet.errors import StiffnetError
from stiffnet.measurement.operating_points import (
    operating_point_configs,
    operating_point_dataset,
    split_evenly,
)
from stiffnet.shipped import default_config


def _rows():
    with open(MANIFEST, encoding="utf-8") as fh:
        return [ManifestRow.model_validate(r) for r in csv.DictReader(fh)]


def _cfg(n: int) -> SimulationConfig:
    cfg = load_config(SimulationConfig, default_config("sim/ideal.yaml"))
    d = cfg.model_dump(mode="json")
    d.update(n_trajectories=n)
    d["windows"]["per_trajectory"] = 1
    return SimulationConfig.model_validate(d)


def test_trajectories_are_split_evenly_over_the_points():
    assert split_evenly(10, 4) == [3, 3, 2, 2]
    assert sum(split_evenly(61, 8)) == 61 and max(split_evenly(61, 8)) == 8


def test_each_config_is_its_rows_point_with_the_sweeps_beta():
    rows = _rows()
    cfgs = operating_point_configs(_cfg(20), rows, jitter=0.05)
    assert [c.n_trajectories for c in cfgs] == split_evenly(20, 8)
    assert {c.shard_size for c in cfgs} == {3}  # one shard size: trajectory numbers unique
    for c, r in zip(cfgs, rows, strict=True):
        sw = c.sweep
        assert sw.gap == pytest.approx((0.95 * r.gap, 1.05 * r.gap))
        assert sw.amplitude == pytest.approx((0.95 * r.amplitude, 1.05 * r.amplitude))
        assert sw.omega == pytest.approx((0.95 * r.frequency_ratio, 1.05 * r.frequency_ratio))
        fs = r.fs_hz / r.natural_frequency_hz
        assert sw.fs_ratio == pytest.approx((0.95 * fs, 1.05 * fs))
        assert sw.noise == pytest.approx((0.019, 0.021)) and sw.noise_levels is None
        assert sw.beta == (5.0, 100.0) and c.effects == cfgs[0].effects


def test_bad_requests_are_one_line():
    with pytest.raises(StiffnetError, match="cannot cover 8 operating points"):
        operating_point_configs(_cfg(5), _rows())
    with pytest.raises(StiffnetError, match="jitter must be"):
        operating_point_configs(_cfg(16), _rows(), jitter=1.5)
    with pytest.raises(StiffnetError, match="no operating points"):
        operating_point_configs(_cfg(16), [])


def test_dataset_draws_every_trajectory_at_its_rows_point(tmp_path):
    rows = _rows()[:4]
    card = operating_point_dataset(_cfg(12), rows, tmp_path / "data", jitter=0.05)
    ds = load_dataset(tmp_path / "data")
    assert card["n_trajectories"] == 12 and len(card["shards"]) == 4
    assert [p["gap"] for p in card["operating_points"]["points"]] == [r.gap for r in rows]
    traj = ds.column("trajectory")
    assert len(np.unique(traj)) == 12
    shard = ds.column("shard")
    for i, r in enumerate(rows):
        on = shard == i
        assert len(np.unique(traj[on])) == 3
        gap, amp = ds.column("gap")[on], ds.column("amplitude")[on]
        assert np.all(np.abs(gap - r.gap) <= 0.05 * r.gap + 1e-12)
        assert np.all(np.abs(amp - r.amplitude) <= 0.05 * r.amplitude + 1e-12)
    # beta is the sweep's: each point's three trajectories are spread over the classes
    assert len(np.unique(ds.column("class"))) >= 3
    # the card's sweep is the box around every point (what the model card reports)
    sweep = card["config"]["sweep"]
    assert sweep["gap"][0] < min(r.gap for r in rows) < max(r.gap for r in rows) < sweep["gap"][1]
    with pytest.raises(StiffnetError, match="not empty"):
        operating_point_dataset(_cfg(12), rows, tmp_path / "data")
