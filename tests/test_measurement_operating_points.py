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
    EDGE_WIDTH,
    class_edges,
    edge_configs,
    hold_orbit,
    operating_point_configs,
    operating_point_dataset,
    point_weights,
    split_evenly,
    split_weighted,
)
from stiffnet.measurement.orbits import window_orbits
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


def test_weighted_split_gives_the_smaller_gaps_more_trajectories():
    # equal weights are the even split; otherwise one each, the rest by largest remainder
    assert split_weighted(61, [2.0] * 8) == split_evenly(61, 8)
    assert split_weighted(10, [1.0, 3.0]) == [3, 7]
    assert split_weighted(3, [1.0, 100.0, 1.0]) == [1, 1, 1]  # no point left without any
    rows = _rows()  # gaps 2.8, 1.2, 2.0, 1.6, 2.4, 0.9, 2.8, 1.2: median 1.8
    assert point_weights(rows, "none") == [1.0] * 8
    w = point_weights(rows, "small_gaps")
    assert w == pytest.approx([1.0, 1.5, 1.0, 1.125, 1.0, 2.0, 1.0, 1.5])  # 1.8 / gap in [1, 2]
    # 32 after one each: quotas 3.16, 4.74, 3.16, 3.56, 3.16, 6.32, 3.16, 4.74
    assert split_weighted(40, w) == [4, 6, 4, 5, 4, 7, 4, 6]
    cfgs = operating_point_configs(_cfg(40), rows, weights="small_gaps")
    assert [c.n_trajectories for c in cfgs] == [4, 6, 4, 5, 4, 7, 4, 6]
    assert {c.shard_size for c in cfgs} == {7}
    assert operating_point_configs(_cfg(40), rows) == operating_point_configs(
        _cfg(40), rows, weights="none"
    )  # equal shares unless asked for
    with pytest.raises(StiffnetError, match="point weights must be one of"):
        point_weights(rows, "large_gaps")
    with pytest.raises(StiffnetError, match="positive and finite"):
        split_weighted(10, [1.0, 0.0])


def test_each_config_is_its_rows_point_with_the_sweeps_beta():
    rows = _rows()
    assert operating_point_configs(_cfg(20), rows) == operating_point_configs(
        _cfg(20), rows, edge_share=0.0
    )  # no edge draws unless asked for
    cfgs = operating_point_configs(_cfg(20), rows, jitter=0.05, edge_share=0.0)
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
    with pytest.raises(StiffnetError, match="near class edges must be in"):
        operating_point_configs(_cfg(16), _rows(), edge_share=1.0)


def test_a_share_of_each_point_is_drawn_near_the_class_edges():
    rows = _rows()
    cfg = _cfg(48)
    assert class_edges(cfg) == [15.0, 35.0, 60.0]  # the shipped classes' inner edges
    cfgs = operating_point_configs(cfg, rows, jitter=0.05, edge_share=0.5)
    # per row: its point over the sweep (3 trajectories), then one config per edge (1 each)
    assert [c.n_trajectories for c in cfgs] == [3, 1, 1, 1] * 8
    assert {c.shard_size for c in cfgs} == {3}
    for k in range(len(rows)):
        main, *edges = cfgs[4 * k : 4 * k + 4]
        assert main.sweep.beta == (5.0, 100.0)
        for c, e in zip(edges, [15.0, 35.0, 60.0], strict=True):
            # the row's point, beta in a band around the edge, as many either side
            assert c.sweep.gap == main.sweep.gap and c.sweep.amplitude == main.sweep.amplitude
            assert c.sweep.beta == pytest.approx((e / (1 + EDGE_WIDTH), e * (1 + EDGE_WIDTH)))
            assert c.sweep.beta_sampling == "stratified"
    # a band is clipped to the sweep; an edge outside the sweep gets none
    d = cfg.model_dump(mode="json")
    d["sweep"]["beta"] = [20.0, 65.0]
    narrow = SimulationConfig.model_validate(d)
    assert class_edges(narrow) == [35.0, 60.0]
    assert [c.sweep.beta for c in edge_configs(narrow, 3)] == pytest.approx(
        [(35 / 1.2, 42.0), (50.0, 65.0)]
    )
    assert [c.n_trajectories for c in edge_configs(narrow, 3)] == [2, 1]
    assert edge_configs(narrow, 0) == []


def test_dataset_draws_every_trajectory_at_its_rows_point(tmp_path):
    rows = _rows()[:4]
    card = operating_point_dataset(_cfg(12), rows, tmp_path / "data", jitter=0.05, edge_share=0)
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


def test_edge_trajectories_straddle_the_edges_at_their_rows_point(tmp_path):
    rows = _rows()[:2]
    card = operating_point_dataset(_cfg(12), rows, tmp_path / "data", jitter=0.05, edge_share=0.5)
    ds = load_dataset(tmp_path / "data")
    ops = card["operating_points"]
    assert ops["edge_share"] == 0.5 and ops["class_edges"] == [15.0, 35.0, 60.0]
    assert len(card["shards"]) == 8 and len(np.unique(ds.column("trajectory"))) == 12
    shard, beta, gap = ds.column("shard"), ds.column("beta"), ds.column("gap")
    for k, r in enumerate(rows):
        assert np.all(np.abs(gap[(shard >= 4 * k) & (shard < 4 * k + 4)] - r.gap) <= 0.05 * r.gap)
        for j, e in enumerate([15.0, 35.0, 60.0]):
            b = beta[shard == 4 * k + 1 + j]
            assert len(b) and np.all((b >= e / 1.2) & (b <= e * 1.2)), (e, b)


def test_shared_batches_draw_each_points_trajectories_as_its_own_shard(tmp_path):
    # shared batches (the default) against each shard alone: the ideal world's closed form
    # does not depend on its batch, so the same draws give the same windows, bit for bit
    rows = _rows()[:3]
    alone = operating_point_dataset(_cfg(9), rows, tmp_path / "a", shared_batches=False)
    shared = operating_point_dataset(_cfg(9), rows, tmp_path / "b")
    assert len(shared["shards"]) == len(alone["shards"]) == 3
    a, b = load_dataset(tmp_path / "a"), load_dataset(tmp_path / "b")
    for col in ("trajectory", "shard", "beta", "gap", "amplitude", "omega", "fs_ratio", "noise"):
        assert np.array_equal(a.column(col), b.column(col)), col
    np.testing.assert_array_equal(np.concatenate(a.windows()), np.concatenate(b.windows()))


def test_the_orbit_hold_keeps_each_rows_windows_on_its_recordings_orbit(tmp_path):
    # at the first point (2.8 mm, forcing 1.05 f_n) the ideal world's windows settle on one
    # impact per period or on two every three periods, by their draws
    rows = _rows()[:2]
    cfg = _cfg(8)
    cfg = cfg.model_copy(update={"windows": cfg.windows.model_copy(update={"per_trajectory": 2})})
    operating_point_dataset(cfg, rows, tmp_path / "free")
    free = load_dataset(tmp_path / "free")
    shard = free.column("shard")
    first = window_orbits(free.table.filter(shard == 0))
    on = first.count((1, 1))
    assert 0 < on < len(first)  # the point mixes orbits
    # row 0's recording on one impact per period; row 1's on an orbit no window reaches
    card = operating_point_dataset(cfg, rows, tmp_path / "held", orbits=[(1, 1), (3, 7)])
    held = load_dataset(tmp_path / "held")
    kept = held.column("shard")
    assert window_orbits(held.table.filter(kept == 0)) == [(1, 1)] * on
    assert np.sum(kept == 1) == np.sum(shard == 1)  # kept whole: the world does not reach it
    info = card["operating_points"]["orbit_hold"]
    assert [(h["held"], h["on_orbit"], h["windows"]) for h in info] == [
        (True, on, len(first)),
        (False, 0, int(np.sum(shard == 1))),
    ]
    # a recording without a repeating orbit, or too few windows on it, keeps the shard whole
    table = free.table.filter(shard == 0)
    assert hold_orbit(table, None)[0].num_rows == len(first)
    assert hold_orbit(table, (1, 1), min_share=1.0)[1]["held"] is False


def test_the_worlds_defaults_come_from_its_shipped_settings():
    """configs/operating_points.yaml validates, is what the module's defaults are, and an
    unknown rule or key is refused."""
    from pydantic import ValidationError

    from stiffnet.measurement import operating_points as op

    shipped = load_config(op.OperatingPointSettings, default_config("operating_points.yaml"))
    assert shipped == op.operating_point_settings()
    assert (op.JITTER, op.EDGE_SHARE, op.WEIGHTS, op.HOLD_ORBITS) == (
        shipped.jitter,
        shipped.edge_share,
        shipped.weights,
        shipped.hold_orbits,
    )
    assert op.RECORD_SUBSTEPS == shipped.record_substeps
    with pytest.raises(ValidationError):
        op.OperatingPointSettings(weights="large_gaps")
    with pytest.raises(ValidationError):
        op.OperatingPointSettings(jiter=0.02)


def test_the_loops_dataset_size_at_the_points_is_the_shipped_setting():
    """A loop iteration at the operating points draws configs/operating_points.yaml's
    ``trajectories`` unless the user gives a number (400 left the model alone limited by its
    data), and a size the loop could not split is refused where the settings are read."""
    from pydantic import ValidationError

    from stiffnet.measurement import loop
    from stiffnet.measurement import operating_points as op

    shipped = load_config(op.OperatingPointSettings, default_config("operating_points.yaml"))
    assert loop.OPERATING_POINT_TRAJECTORIES == op.TRAJECTORIES == shipped.trajectories
    assert shipped.trajectories >= 1600
    with pytest.raises(ValidationError):
        op.OperatingPointSettings(trajectories=loop.MIN_TRAJECTORIES - 1)
    assert op.OperatingPointSettings(trajectories=loop.MIN_TRAJECTORIES).trajectories == 50
