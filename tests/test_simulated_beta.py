"""Beta by simulation (stiffnet.measurement.simulated_beta) and its place in evaluate.

A campaign stiffnet simulates at known betas (the linear law, the closed-form engine, its
own seed and noise) is read back by simulating at other initial states and noise; a
recording whose manifest misstates its forcing frequency is reproduced by no beta and
must say so.
"""

from __future__ import annotations

import csv
import shutil

import numpy as np
import pytest
from campaign_helpers import short_manifest

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.errors import ConfigError
from stiffnet.measurement.metrics import true_class
from stiffnet.measurement.simulated_beta import (
    SimulatedBetaConfig,
    beta_by_least_discrepancy,
    beta_interval,
    load_simulated_beta_config,
    simulated_beta_config,
)
from stiffnet.measurement.simulation_reading import _add_row, disjoint_alarm

#: Four recordings of the example manifest (beta 8, 14, 22, 30), 3 s each.
N_ROWS = 4


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("simbeta")
    return load_campaign(simulate_campaign(short_manifest(tmp, N_ROWS), tmp / "c", [], seed=0))


@pytest.fixture(scope="module")
def reading(campaign):
    return beta_by_least_discrepancy(campaign, [])


def test_reads_back_the_betas_it_was_simulated_at(campaign, reading):
    for row, r in zip(campaign.rows, reading["recordings"], strict=True):
        assert r["beta"] == pytest.approx(row.beta, rel=0.05), r["reason"]
        assert r["beta_interval"][0] <= row.beta <= r["beta_interval"][1]
        assert r["reproduced"], r["reason"]
        assert r["class"] == true_class(row.beta, True)
    assert reading["simulated"] == N_ROWS * (9 + 2)  # coarse grid, then one beta per side


def test_flags_a_recording_no_beta_reproduces(campaign, tmp_path):
    # the manifest misstates one recording's forcing frequency by 30 %
    folder = tmp_path / "wrong"
    shutil.copytree(campaign.folder, folder)
    with open(folder / "manifest.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    rows[1]["frequency_ratio"] = str(1.3 * float(rows[1]["frequency_ratio"]))
    with open(folder / "manifest.csv", "w", encoding="utf-8", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    res = beta_by_least_discrepancy(load_campaign(folder), [])["recordings"]
    assert res[1]["reproduced"] is False, res[1]["reason"]
    assert "no beta reproduces it" in res[1]["reason"]
    assert [r["reproduced"] for i, r in enumerate(res) if i != 1] == [True] * (N_ROWS - 1)


def test_interval_of_a_parabolic_profile():
    beta0, a, d0 = 23.0, 40.0, 0.1
    betas = np.exp(np.linspace(np.log(4), np.log(125), 9))
    betas = np.sort(np.r_[betas, 20.0, 26.0])
    d = a * (np.log(betas) - np.log(beta0)) ** 2 + d0
    beta, low, high, edge = beta_interval(betas, d, 0.2)
    assert beta == pytest.approx(beta0, rel=1e-9)
    half = np.sqrt(0.2 / a)  # the rise above the vertex
    assert (low, high) == pytest.approx((beta0 * np.exp(-half), beta0 * np.exp(half)), rel=1e-9)
    assert not edge
    # a profile falling to the grid's edge: the interval is open there
    beta, low, high, edge = beta_interval(betas, -np.log(betas), 0.5)
    assert beta == betas[-1] and high == betas[-1] and edge


def test_config_is_validated(tmp_path):
    assert simulated_beta_config().enabled  # the shipped YAML loads
    with pytest.raises(ValueError, match="beta_range"):
        SimulatedBetaConfig(beta_range=(50.0, 10.0))
    bad = tmp_path / "s.yaml"
    bad.write_text("coarse_points: 2\nreproduce_facter: 3\n", encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        load_simulated_beta_config(bad)
    assert "\n" not in str(err.value) and "coarse_points" in str(err.value)


def test_disjoint_intervals_alarm_only_where_reproduced():
    sim = {"beta_interval": [40.0, 50.0], "reproduced": True}
    assert disjoint_alarm([10.0, 30.0], sim) is True
    assert disjoint_alarm([30.0, 45.0], sim) is False
    assert disjoint_alarm([10.0, 30.0], {**sim, "reproduced": False}) is False
    assert disjoint_alarm(None, sim) is None


def test_a_reading_the_model_does_not_exclude_is_undecided():
    sim = {"class": "hard", "beta": 53.3, "beta_interval": [33.6, 84.5], "floor_ratio": 1.5,
           "reproduced": True, "reason": ""}  # fmt: skip

    def row(cls, interval):
        r = {"class": cls, "beta_estimate": 81.4, "beta_interval": interval}
        _add_row(r, sim, reading=True)
        return r

    # another class, overlapping intervals: the reading takes the simulation's, undecided
    r = row("very_hard", [62.7, 105.6])
    assert (r["reading_method"], r["reading_class"]) == ("simulation", "hard")
    assert r["reading_undecided"] is True and r["simulation_alarm"] is False
    # the same class, or intervals that exclude each other (the simulation's alarm): decided
    assert row("hard", [40.0, 60.0])["reading_undecided"] is False
    far = row("very_hard", [90.0, 120.0])
    assert far["reading_undecided"] is False and far["simulation_alarm"] is True
    # not reproduced: the model's reading, nothing to decide
    sim["reproduced"] = False
    assert row("very_hard", [62.7, 105.6])["reading_undecided"] is False


def test_evaluate_reports_the_simulation_and_the_reading(campaign):
    from stiffnet.measurement.evaluate import evaluate_campaign

    res = evaluate_campaign(campaign)
    m = res["metrics"]
    assert {"learned", "geometric", "restoring_force", "simulation", "reading"} <= set(m)
    sim = m["simulation"]
    assert sim["read"] == N_ROWS and sim["accuracy"] == 1.0 and sim["beta_mape"] < 0.05
    assert sim["interval_coverage"] == 1.0 and sim["reproduced_share"] == 1.0
    assert res["simulation"]["ran"] and res["simulation"]["cpu_seconds"]["total"] > 0
    for r in res["recordings"]:
        assert r["reading_method"] == "simulation"  # reproduced everywhere
        assert (r["reading_class"], r["reading_beta"]) == (
            r["simulation_class"],
            r["simulation_beta"],
        )
        assert "class" in r and "beta_estimate" in r  # the model's own figures stay
    assert m["reading"]["from_simulation"] == N_ROWS
    assert m["reading"]["wrong_silent"] == 0
    off = evaluate_campaign(campaign, simulation=SimulatedBetaConfig(enabled=False))
    assert "simulation" not in off["metrics"] and off["simulation"]["ran"] is False
