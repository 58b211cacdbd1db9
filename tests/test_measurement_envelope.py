"""The loop's training world narrowed to the campaign's operating envelope."""

from __future__ import annotations

import csv

import pytest
from campaign_helpers import MANIFEST

from stiffnet.campaign.manifest import ManifestRow
from stiffnet.config import load_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.measurement.envelope import campaign_envelope, envelope_range
from stiffnet.shipped import default_config


def _rows():
    with open(MANIFEST, encoding="utf-8") as fh:
        return [ManifestRow.model_validate(r) for r in csv.DictReader(fh)]


def test_range_is_widened_by_the_margin_of_its_width_or_value():
    assert envelope_range([1.0, 2.0], 0.1) == pytest.approx((0.8, 2.2))
    assert envelope_range([0.02, 0.02], 0.1) == pytest.approx((0.018, 0.022))


def test_sweep_covers_every_row_and_moves_where_the_config_does_not_reach():
    cfg = load_config(SimulationConfig, default_config("sim/ideal.yaml"))
    d = cfg.model_dump(mode="json")
    d["sweep"].update(fs_ratio=[60, 120], noise_levels=[0.0, 0.1])
    out = campaign_envelope(SimulationConfig.model_validate(d), _rows())
    sw, rows = out.sweep, _rows()
    # the example campaign: gap 0.9-2.8, amplitude 1.2-1.9, fs/f_n 105-211, noise 0.02
    assert sw.gap == pytest.approx((0.9 - 0.28, 2.8 + 0.28))
    assert sw.amplitude == pytest.approx((1.2 - 0.19, 1.9 + 0.19))
    assert sw.fs_ratio[0] < 1000 / 9.48 and sw.fs_ratio[1] > 2000 / 9.48 > 120
    assert sw.noise == pytest.approx((0.018, 0.022)) and sw.noise_levels is None
    for r in rows:
        assert sw.omega[0] < r.frequency_ratio < sw.omega[1]
        assert sw.damping[0] < r.damping_ratio < sw.damping[1]
    assert sw.beta == cfg.sweep.beta and out.effects == cfg.effects  # the rest is kept


def test_a_column_no_row_gives_keeps_the_configs_range():
    cfg = load_config(SimulationConfig, default_config("sim/ideal.yaml"))
    rows = [r.model_copy(update={"gap": None, "noise": None}) for r in _rows()]
    sw = campaign_envelope(cfg, rows).sweep
    assert sw.gap == cfg.sweep.gap
    assert sw.amplitude != cfg.sweep.amplitude
